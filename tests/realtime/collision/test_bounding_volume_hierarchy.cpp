// The bounding-volume hierarchy against brute force over every triangle (independent
// Möller–Trumbore, projection and winding-number implementations), against Embree, after a
// refit, on degenerate input, and its counters. One file for the build and the query sources:
// every case builds trees to query them, against the same brute force and test surfaces.
#include "support/embree_scene.hpp"
#include "support/test_surfaces.hpp"
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <ostream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace touchstone::realtime::collision {
namespace {

using touchstone::testing::EmbreeScene;
using touchstone::testing::torus;

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::Vector3i;
using geometry::TriangleMeshData;

constexpr double pi = 3.14159265358979323846;
constexpr double radius = 0.05;  // [m], the paper's hemisphere scale
constexpr double infinity = std::numeric_limits<double>::infinity();
constexpr double nan = std::numeric_limits<double>::quiet_NaN();

using Mesh = TriangleMeshData;

// ---------------------------------------------------------------------------------------------
// Surfaces.

/// An icosphere whose vertices are moved radially: r(d̂) = radius · f(d̂) (star-shaped, so
/// still closed and embedded for f > 0).
template <class RadiusFactor>
Mesh radial_surface(int level, RadiusFactor factor) {
  Mesh mesh = geometry::icosphere(level, 1.0);
  for (Vector3d& v : mesh.vertices) v = radius * factor(v) * v;
  return mesh;
}

/// Ellipsoid with semi-axes (1, 0.7, 0.45) R, each vertex moved radially by up to ±2 %.
Mesh perturbed_ellipsoid() {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> noise(-0.02, 0.02);
  Mesh mesh = geometry::icosphere(3, 1.0);
  for (Vector3d& v : mesh.vertices) v = radius * (1 + noise(random)) * Vector3d(v.x(), 0.7 * v.y(), 0.45 * v.z());
  return mesh;
}

/// Three lobes around z and flattened poles: r = R (1 + 0.4 (x³ − 3xy²)) (concave between lobes).
Mesh lobed_surface() {
  return radial_surface(4, [](const Vector3d& d) { return 1 + 0.4 * (d.x() * d.x() * d.x() - 3 * d.x() * d.y() * d.y()); });
}

/// Axis-aligned cube [−h, h]³, two triangles per face, outward.
Mesh cube(double h) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) mesh.vertices.push_back({(i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h});
  mesh.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Brute force, written independently of the library's primitives.

struct BruteHit {
  bool hit = false;
  double t = infinity;
  int triangle = -1;
};

/// First t ∈ [0, t_end] of origin + t·direction over every triangle (Möller–Trumbore, both sides).
BruteHit brute_first_hit(const Mesh& mesh, const Vector3d& origin, const Vector3d& direction, double t_end) {
  BruteHit best;
  for (int i = 0; i < static_cast<int>(mesh.triangles.size()); ++i) {
    const Vector3d& a = mesh.vertices[mesh.triangles[i][0]];
    const Vector3d e1 = mesh.vertices[mesh.triangles[i][1]] - a;
    const Vector3d e2 = mesh.vertices[mesh.triangles[i][2]] - a;
    const Vector3d p = direction.cross(e2);
    const double det = e1.dot(p);
    if (det == 0) continue;
    const Vector3d s = origin - a;
    const double u = s.dot(p) / det;
    if (u < 0 || u > 1) continue;
    const Vector3d q = s.cross(e1);
    const double v = direction.dot(q) / det;
    if (v < 0 || u + v > 1) continue;
    const double t = e2.dot(q) / det;
    if (t < 0 || t > t_end || t >= best.t) continue;
    best = {true, t, i};
  }
  return best;
}

struct BruteClosest {
  double distance = infinity;
  int triangle = -1;
};

/// Closest triangle: the projection onto the plane when it falls inside, else the nearest edge.
BruteClosest brute_closest(const Mesh& mesh, const Vector3d& x) {
  BruteClosest best;
  const auto segment = [&](const Vector3d& s, const Vector3d& e) {
    const double u = std::clamp((x - s).dot(e - s) / (e - s).squaredNorm(), 0.0, 1.0);
    return (s + u * (e - s) - x).squaredNorm();
  };
  for (int i = 0; i < static_cast<int>(mesh.triangles.size()); ++i) {
    const Vector3d& a = mesh.vertices[mesh.triangles[i][0]];
    const Vector3d& b = mesh.vertices[mesh.triangles[i][1]];
    const Vector3d& c = mesh.vertices[mesh.triangles[i][2]];
    const Vector3d n = (b - a).cross(c - a);
    const Vector3d q = x - n * ((x - a).dot(n) / n.squaredNorm());
    double d;
    if ((b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 && (a - c).cross(q - c).dot(n) >= 0) {
      d = (x - q).squaredNorm();
    } else {
      d = std::min({segment(a, b), segment(b, c), segment(c, a)});
    }
    if (d < best.distance * best.distance) best = {std::sqrt(d), i};
  }
  return best;
}

/// Generalised winding number (Van Oosterom & Strackee solid angles): 1 inside, 0 outside.
double winding_number(const Mesh& mesh, const Vector3d& x) {
  double sum = 0;
  for (const Vector3i& t : mesh.triangles) {
    const Vector3d a = mesh.vertices[t[0]] - x;
    const Vector3d b = mesh.vertices[t[1]] - x;
    const Vector3d c = mesh.vertices[t[2]] - x;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    sum += 2 * std::atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
  }
  return sum / (4 * pi);
}

Vector3d face_normal(const Mesh& mesh, int triangle) {
  const Vector3i& t = mesh.triangles[triangle];
  return (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]).normalized();
}

// ---------------------------------------------------------------------------------------------
// Random queries, scaled to the surface's size.

struct SegmentQuery {
  Vector3d from, to;
};
struct RayQuery {
  Vector3d origin, direction;
  double max_distance;
};

struct Queries {
  std::vector<SegmentQuery> segments;
  std::vector<RayQuery> rays;
  std::vector<Vector3d> points;     ///< closest point
  std::vector<Vector3d> contained;  ///< contains
};

class QueryMaker {
 public:
  QueryMaker(const Mesh& mesh, std::uint64_t seed) : mesh_(mesh), random_(seed) {
    lower_ = upper_ = mesh.vertices[0];
    for (const Vector3d& v : mesh.vertices) {
      lower_ = lower_.cwiseMin(v);
      upper_ = upper_.cwiseMax(v);
    }
    scale_ = (upper_ - lower_).norm();
  }

  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(random_); }
  Vector3d unit_vector() {
    std::normal_distribution<double> normal;
    Vector3d v(normal(random_), normal(random_), normal(random_));
    return v.normalized();
  }
  /// Uniform in the bounding box grown by `grow` times its size about its centre.
  Vector3d in_box(double grow) {
    const Vector3d center = 0.5 * (lower_ + upper_);
    const Vector3d half = 0.5 * grow * (upper_ - lower_);
    return center + Vector3d(uniform(-1, 1) * half.x(), uniform(-1, 1) * half.y(), uniform(-1, 1) * half.z());
  }
  /// A random point on a random triangle, offset along its normal by up to ±offset.
  Vector3d near_surface(double offset) {
    const int t = std::uniform_int_distribution<int>(0, static_cast<int>(mesh_.triangles.size()) - 1)(random_);
    double u = uniform(0, 1), v = uniform(0, 1);
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Vector3i& tri = mesh_.triangles[t];
    const Vector3d p = mesh_.vertices[tri[0]] + u * (mesh_.vertices[tri[1]] - mesh_.vertices[tri[0]]) +
                       v * (mesh_.vertices[tri[2]] - mesh_.vertices[tri[0]]);
    return p + uniform(-offset, offset) * face_normal(mesh_, t);
  }

  Queries make(int count, int contains_count) {
    Queries q;
    // Tool-tip moves (0.1–3 mm at R = 50 mm) starting within 2 mm of the surface, and long
    // segments across the box (several hits each).
    const double mm = scale_ / (4 * radius) * 1e-3;
    for (int i = 0; i < count; ++i) {
      if (i % 3 != 2) {
        const Vector3d from = near_surface(2 * mm);
        q.segments.push_back({from, from + uniform(0.1, 3) * mm * unit_vector()});
      } else {
        q.segments.push_back({in_box(1.3), in_box(1.3)});
      }
    }
    for (int i = 0; i < count; ++i) {
      const double max_distance = i % 2 == 0 ? infinity : uniform(0, 0.7 * scale_);
      q.rays.push_back({in_box(1.5), unit_vector(), max_distance});
    }
    for (int i = 0; i < count; ++i) {
      switch (i % 3) {
        case 0: q.points.push_back(near_surface(2 * mm)); break;
        case 1: q.points.push_back(in_box(1.2)); break;
        default: q.points.push_back(0.5 * (lower_ + upper_) + uniform(1, 3) * scale_ * unit_vector()); break;
      }
    }
    for (int i = 0; i < contains_count; ++i) {
      q.contained.push_back(i % 2 == 0 ? in_box(1.2) : near_surface(0.1 * mm));
    }
    return q;
  }

  double scale() const { return scale_; }

 private:
  const Mesh& mesh_;
  std::mt19937_64 random_;
  Vector3d lower_, upper_;
  double scale_ = 0;
};

/// |a − b| ≤ 1e-12 max(|a|, |b|), with an absolute floor of 1e-15 of the surface size for
/// distances near zero.
bool same_distance(double a, double b, double scale) {
  return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)) + 1e-15 * scale;
}

struct Configuration {
  BvhSettings settings;
  std::string name;
};

std::vector<Configuration> configurations() {
  std::vector<Configuration> list;
  const auto add = [&](BoundingVolume volume, int width, int leaf, SplitRule split, double grid, const std::string& name) {
    BvhSettings settings;
    settings.bounding_volume = volume;
    settings.children_per_node = width;
    settings.max_leaf_triangles = leaf;
    settings.split = split;
    settings.entry_grid_cell = grid;
    list.push_back({settings, name});
  };
  add(BoundingVolume::obb, 4, 1, SplitRule::median, 2, "obb 4-wide leaf 1");
  add(BoundingVolume::aabb, 4, 1, SplitRule::median, 2, "aabb 4-wide leaf 1");
  add(BoundingVolume::obb, 2, 1, SplitRule::median, 0, "obb binary leaf 1 no grid");
  add(BoundingVolume::aabb, 2, 1, SplitRule::median, 1, "aabb binary leaf 1 grid 1");
  add(BoundingVolume::obb, 4, 4, SplitRule::mean, 5, "obb 4-wide leaf 4 mean split grid 5");
  add(BoundingVolume::aabb, 2, 3, SplitRule::mean, 2, "aabb binary leaf 3 mean split");
  return list;
}

/// Every query of `queries` through every configuration equals brute force on `mesh`.
void expect_brute_force_equality(const Mesh& mesh, const std::vector<const BoundingVolumeHierarchy*>& trees,
                                 const std::vector<std::string>& names, const Queries& queries, double scale) {
  int ties = 0;
  int hits = 0;
  for (std::size_t i = 0; i < queries.segments.size(); ++i) {
    const SegmentQuery& s = queries.segments[i];
    const Vector3d direction = s.to - s.from;
    const BruteHit expected = brute_first_hit(mesh, s.from, direction, 1);
    hits += expected.hit;
    for (std::size_t k = 0; k < trees.size(); ++k) {
      const SurfaceHit hit = trees[k]->first_hit_segment(s.from, s.to);
      ASSERT_EQ(hit.hit, expected.hit) << names[k] << ", segment " << i;
      if (!hit.hit) {
        EXPECT_EQ(hit.triangle, -1);
        continue;
      }
      const double distance = expected.t * direction.norm();
      ASSERT_TRUE(same_distance(hit.distance_m, distance, scale))
          << names[k] << ", segment " << i << ": " << hit.distance_m << " vs " << distance;
      ties += hit.triangle != expected.triangle;
      ASSERT_GE(hit.triangle, 0);
      EXPECT_LT((hit.normal - face_normal(mesh, hit.triangle)).norm(), 1e-12);
      EXPECT_LT((hit.point - (s.from + hit.distance_m * direction.normalized())).norm(), 1e-12 * scale);
    }
  }
  EXPECT_GT(hits, static_cast<int>(queries.segments.size()) / 10) << "the segments should often cross the surface";

  for (std::size_t i = 0; i < queries.rays.size(); ++i) {
    const RayQuery& r = queries.rays[i];
    const BruteHit expected = brute_first_hit(mesh, r.origin, r.direction, r.max_distance);
    for (std::size_t k = 0; k < trees.size(); ++k) {
      const SurfaceHit hit = trees[k]->first_hit_ray(r.origin, r.direction, r.max_distance);
      ASSERT_EQ(hit.hit, expected.hit) << names[k] << ", ray " << i;
      if (!hit.hit) continue;
      ASSERT_TRUE(same_distance(hit.distance_m, expected.t, scale))
          << names[k] << ", ray " << i << ": " << hit.distance_m << " vs " << expected.t;
      ties += hit.triangle != expected.triangle;
    }
  }

  for (std::size_t i = 0; i < queries.points.size(); ++i) {
    const Vector3d& x = queries.points[i];
    const BruteClosest expected = brute_closest(mesh, x);
    for (std::size_t k = 0; k < trees.size(); ++k) {
      const ClosestSurfacePoint closest = trees[k]->closest_point(x);
      ASSERT_GE(closest.triangle, 0);
      ASSERT_TRUE(same_distance(closest.distance_m, expected.distance, scale))
          << names[k] << ", point " << i << ": " << closest.distance_m << " vs " << expected.distance;
      EXPECT_TRUE(same_distance((closest.point - x).norm(), closest.distance_m, scale));
      ties += closest.triangle != expected.triangle;
    }
  }

  for (std::size_t i = 0; i < queries.contained.size(); ++i) {
    const Vector3d& x = queries.contained[i];
    const bool expected = winding_number(mesh, x) > 0.5;
    for (std::size_t k = 0; k < trees.size(); ++k) {
      ASSERT_EQ(trees[k]->contains(x), expected) << names[k] << ", point " << i << " (" << x.transpose() << ")";
    }
  }
  // Equal distances on different triangles happen only where triangles meet (closest points at
  // vertices and edges): a minority.
  const std::size_t total = queries.segments.size() + queries.rays.size() + queries.points.size();
  EXPECT_LT(ties, static_cast<int>(trees.size() * total / 2));
}

struct MeshCase {
  std::string name;
  Mesh (*make)();
  int queries;
};

void PrintTo(const MeshCase& mesh_case, std::ostream* out) { *out << mesh_case.name; }

class BruteForce : public ::testing::TestWithParam<MeshCase> {};

TEST_P(BruteForce, EveryQueryEqualsBruteForce) {
  const Mesh mesh = GetParam().make();
  const geometry::TriangleSurface surface(mesh.vertices, mesh.triangles, GetParam().name);
  std::vector<BoundingVolumeHierarchy> trees;
  std::vector<std::string> names;
  for (const Configuration& c : configurations()) {
    trees.emplace_back(surface, c.settings);
    names.push_back(c.name);
  }
  std::vector<const BoundingVolumeHierarchy*> pointers;
  for (const BoundingVolumeHierarchy& tree : trees) pointers.push_back(&tree);

  QueryMaker maker(mesh, 1234);
  const int contains_count = std::clamp(static_cast<int>(4e6 / mesh.triangles.size()), 150, GetParam().queries);
  const Queries queries = maker.make(GetParam().queries, contains_count);
  expect_brute_force_equality(mesh, pointers, names, queries, maker.scale());
}

INSTANTIATE_TEST_SUITE_P(
    Surfaces, BruteForce,
    ::testing::Values(MeshCase{"icosphere_2", [] { return geometry::icosphere(2, radius); }, 3000},
                      MeshCase{"icosphere_3", [] { return geometry::icosphere(3, radius); }, 3000},
                      MeshCase{"icosphere_4", [] { return geometry::icosphere(4, radius); }, 1500},
                      MeshCase{"icosphere_5", [] { return geometry::icosphere(5, radius); }, 500},
                      MeshCase{"perturbed_ellipsoid", perturbed_ellipsoid, 3000},
                      MeshCase{"lobed", lobed_surface, 1500},
                      MeshCase{"torus", [] { return torus(64, 24, 0.7 * radius, 0.25 * radius); }, 3000},
                      MeshCase{"cube", [] { return cube(radius); }, 3000}),
    [](const ::testing::TestParamInfo<MeshCase>& info) { return info.param.name; });

// ---------------------------------------------------------------------------------------------
// Embree (float) as an independent oracle for first-hit rays.


/// Distance from p (in the plane of triangle t) to the triangle's boundary.
double distance_to_edges(const Mesh& mesh, int triangle, const Vector3d& p) {
  double best = infinity;
  for (int k = 0; k < 3; ++k) {
    const Vector3d& a = mesh.vertices[mesh.triangles[triangle][k]];
    const Vector3d& b = mesh.vertices[mesh.triangles[triangle][(k + 1) % 3]];
    const double u = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + u * (b - a) - p).norm());
  }
  return best;
}

TEST(BoundingVolumeHierarchy, FirstHitRaysAgreeWithEmbree) {
  for (const Mesh& mesh : {geometry::icosphere(4, radius), torus(64, 24, 0.7 * radius, 0.25 * radius), lobed_surface()}) {
    const EmbreeScene embree(mesh.vertices, mesh.triangles);
    const BoundingVolumeHierarchy obb(mesh.vertices, mesh.triangles);
    QueryMaker maker(mesh, 99);
    // Float precision: coordinates to ~6e-8 relative, so agreement to 1e-5 of the size, and
    // misses only where the double hit lies within 1e-6 of the size from a triangle's edge.
    const double tolerance = 1e-5 * maker.scale();
    int hits = 0;
    int grazing = 0;
    for (int i = 0; i < 3000; ++i) {
      const Vector3d origin = maker.in_box(1.5);
      const Vector3d direction = maker.unit_vector();
      const double max_distance = i % 2 == 0 ? infinity : maker.uniform(0, 0.7 * maker.scale());
      const SurfaceHit hit = obb.first_hit_ray(origin, direction, max_distance);
      const auto [t, triangle] = embree.first_hit(origin, direction, max_distance);
      if (hit.hit != (triangle >= 0)) {
        // Float rounding decides only hits at the very edge of a triangle or of [0, max].
        ASSERT_TRUE(hit.hit) << "ray " << i << " hit by Embree only";
        const bool near_end = std::abs(hit.distance_m - max_distance) < tolerance;
        ASSERT_TRUE(near_end || distance_to_edges(mesh, hit.triangle, hit.point) < 1e-6 * maker.scale())
            << "ray " << i << " missed by Embree";
        ++grazing;
        continue;
      }
      if (!hit.hit) continue;
      ++hits;
      ASSERT_NEAR(hit.distance_m, t, tolerance) << "ray " << i;
      if (hit.triangle != triangle) {
        EXPECT_LT(distance_to_edges(mesh, hit.triangle, hit.point), 1e-6 * maker.scale()) << "ray " << i;
      }
    }
    EXPECT_GT(hits, 500);
    EXPECT_LE(grazing, 3);
  }
}

// ---------------------------------------------------------------------------------------------
// Refit.

TEST(BoundingVolumeHierarchy, RefitMatchesBruteForceOnTheDeformedSurface) {
  const Mesh mesh = geometry::icosphere(3, radius);
  // A smooth dent at the north pole, 30 % of the radius deep (the surface becomes non-convex),
  // and a gentle stretch along x.
  Mesh deformed = mesh;
  const Vector3d pole(0, 0, radius);
  for (Vector3d& v : deformed.vertices) {
    const double bump = 0.3 * radius * std::exp(-(v - pole).squaredNorm() / std::pow(0.4 * radius, 2));
    v = v - bump * v.normalized();
    v.x() *= 1.15;
  }
  std::vector<BoundingVolumeHierarchy> trees;
  std::vector<std::string> names;
  for (const Configuration& c : configurations()) {
    trees.emplace_back(mesh.vertices, mesh.triangles, c.settings);
    trees.back().refit(deformed.vertices);
    names.push_back(c.name + " refitted");
  }
  std::vector<const BoundingVolumeHierarchy*> pointers;
  for (const BoundingVolumeHierarchy& tree : trees) pointers.push_back(&tree);
  QueryMaker maker(deformed, 5);
  expect_brute_force_equality(deformed, pointers, names, maker.make(2000, 1000), maker.scale());
  EXPECT_EQ(trees[0].vertices(), deformed.vertices);

  // Refitting back gives the original tree's answers.
  trees[0].refit(mesh.vertices);
  const BoundingVolumeHierarchy fresh(mesh.vertices, mesh.triangles);
  QueryMaker again(mesh, 6);
  const Queries queries = again.make(300, 0);
  for (const SegmentQuery& s : queries.segments) {
    const SurfaceHit a = trees[0].first_hit_segment(s.from, s.to);
    const SurfaceHit b = fresh.first_hit_segment(s.from, s.to);
    ASSERT_EQ(a.hit, b.hit);
    EXPECT_EQ(a.distance_m, b.distance_m);
  }
}

TEST(BoundingVolumeHierarchy, RefitRejectsWrongSizeAndNonFiniteVerticesAndKeepsTheTree) {
  const Mesh mesh = geometry::icosphere(2, radius);
  BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles);
  std::vector<Vector3d> shorter(mesh.vertices.begin(), mesh.vertices.end() - 1);
  EXPECT_THROW(tree.refit(shorter), std::invalid_argument);
  std::vector<Vector3d> broken = mesh.vertices;
  broken[17].y() = nan;
  try {
    tree.refit(broken);
    FAIL() << "a NaN vertex must be rejected";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("vertex 17"), std::string::npos) << error.what();
  }
  broken[17].y() = infinity;
  EXPECT_THROW(tree.refit(broken), std::invalid_argument);
  EXPECT_EQ(tree.vertices(), mesh.vertices);
  const SurfaceHit hit = tree.first_hit_segment(Vector3d(0, 0, 2 * radius), Vector3d::Zero());
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.distance_m, radius, 0.02 * radius);
}

// ---------------------------------------------------------------------------------------------
// Degenerate input.

class Degenerate : public ::testing::TestWithParam<BoundingVolume> {
 protected:
  BvhSettings settings() const {
    BvhSettings s;
    s.bounding_volume = GetParam();
    return s;
  }
};

TEST_P(Degenerate, ZeroLengthAndNonFiniteQueriesGiveNoHit) {
  const Mesh mesh = geometry::icosphere(3, radius);
  const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles, settings());
  QueryCounters counters;
  const Vector3d vertex = mesh.vertices[5];
  for (const Vector3d& p : {vertex, Vector3d(0, 0, 0), Vector3d(1, 1, 1)}) {
    const SurfaceHit hit = tree.first_hit_segment(p, p, &counters);
    EXPECT_FALSE(hit.hit);
    EXPECT_EQ(hit.triangle, -1);
  }
  const Vector3d bad[] = {Vector3d(nan, 0, 0), Vector3d(0, infinity, 0), Vector3d(0, 0, -infinity)};
  for (const Vector3d& p : bad) {
    for (const SurfaceHit& hit : {tree.first_hit_segment(p, Vector3d::Zero(), &counters),
                                  tree.first_hit_segment(Vector3d(0, 0, 2 * radius), p, &counters),
                                  tree.first_hit_ray(p, Vector3d(0, 0, 1), infinity, &counters),
                                  tree.first_hit_ray(Vector3d::Zero(), p, infinity, &counters)}) {
      EXPECT_FALSE(hit.hit);
      EXPECT_EQ(hit.triangle, -1);
      EXPECT_TRUE(hit.point.allFinite());
    }
    const ClosestSurfacePoint closest = tree.closest_point(p, &counters);
    EXPECT_EQ(closest.triangle, -1);
    EXPECT_EQ(closest.distance_m, infinity);
    EXPECT_TRUE(closest.point.allFinite());
    EXPECT_FALSE(tree.contains(p, &counters));
  }
  // Zero direction, NaN or negative reach.
  EXPECT_FALSE(tree.first_hit_ray(Vector3d::Zero(), Vector3d::Zero(), infinity).hit);
  EXPECT_FALSE(tree.first_hit_ray(Vector3d::Zero(), Vector3d(1, 0, 0), nan).hit);
  EXPECT_FALSE(tree.first_hit_ray(Vector3d::Zero(), Vector3d(1, 0, 0), -1).hit);
  // Enormous but finite coordinates: defined answers, no NaN.
  const Vector3d far(1e300, -1e300, 1e300);
  for (const SurfaceHit& hit : {tree.first_hit_segment(far, -far), tree.first_hit_segment(far, Vector3d::Zero()),
                                tree.first_hit_ray(far, -far, infinity)}) {
    if (hit.hit) {
      EXPECT_TRUE(hit.point.allFinite() && std::isfinite(hit.distance_m));
    }
  }
  const ClosestSurfacePoint closest = tree.closest_point(far);
  EXPECT_GE(closest.triangle, 0);
  EXPECT_FALSE(std::isnan(closest.distance_m));
  EXPECT_FALSE(tree.contains(far));
  // Every call was counted as a query, with no work for the rejected ones.
  EXPECT_EQ(counters.queries, 3 + 3 * 6);
  EXPECT_EQ(counters.box_tests, 0);
  EXPECT_EQ(counters.triangle_tests, 0);
}

TEST_P(Degenerate, SegmentsThroughEveryVertexAndEdgeHit) {
  // Watertightness: a segment exactly through a vertex or through an edge's midpoint hits one of
  // the triangles there, at the expected distance.
  const Mesh mesh = geometry::icosphere(2, radius);
  const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles, settings());
  const double offset = 1e-3;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Vector3d p = mesh.vertices[v];
    const Vector3d n = p.normalized();
    using Segment = std::pair<Vector3d, Vector3d>;
    for (const auto& [from, to] : {Segment(p + offset * n, p - offset * n), Segment(p - offset * n, p + offset * n)}) {
      const SurfaceHit hit = tree.first_hit_segment(from, to);
      ASSERT_TRUE(hit.hit) << "vertex " << v;
      EXPECT_NEAR(hit.distance_m, offset, 1e-12);
      const Vector3i& t = mesh.triangles[hit.triangle];
      EXPECT_TRUE(t[0] == static_cast<int>(v) || t[1] == static_cast<int>(v) || t[2] == static_cast<int>(v));
    }
    const ClosestSurfacePoint closest = tree.closest_point(p);
    EXPECT_EQ(closest.distance_m, 0);
    EXPECT_EQ(closest.point, p);
    EXPECT_FALSE(tree.contains(p)) << "a vertex is on the surface, not strictly inside";
    EXPECT_TRUE(tree.contains(p - 1e-9 * n));
    EXPECT_FALSE(tree.contains(p + 1e-9 * n));
  }
  for (const Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const Vector3d p = 0.5 * (mesh.vertices[t[k]] + mesh.vertices[t[(k + 1) % 3]]);
      const Vector3d n = p.normalized();
      const SurfaceHit hit = tree.first_hit_segment(p + offset * n, p - offset * n);
      ASSERT_TRUE(hit.hit);
      EXPECT_NEAR(hit.distance_m, offset, 1e-12);
      EXPECT_TRUE(tree.contains(p - 1e-9 * n));
      EXPECT_FALSE(tree.contains(p + 1e-9 * n));
    }
  }
}

TEST_P(Degenerate, RaysParallelToAFace) {
  const double h = radius;
  const Mesh box = cube(h);
  const BoundingVolumeHierarchy tree(box.vertices, box.triangles, settings());
  // Above the top face: no hit. Just below: the side face x = −h at distance h.
  EXPECT_FALSE(tree.first_hit_ray(Vector3d(-2 * h, 0.1 * h, h * (1 + 1e-12)), Vector3d(1, 0, 0), infinity).hit);
  const SurfaceHit below = tree.first_hit_ray(Vector3d(-2 * h, 0.1 * h, h * (1 - 1e-12)), Vector3d(1, 0, 0), infinity);
  ASSERT_TRUE(below.hit);
  EXPECT_NEAR(below.distance_m, h, 1e-15);
  EXPECT_NEAR(below.normal.x(), -1, 1e-15);
  // In the top face's plane: touching the top edge of the side face. Whatever the answer, it is
  // finite and on the surface.
  const SurfaceHit in_plane = tree.first_hit_ray(Vector3d(-2 * h, 0.1 * h, h), Vector3d(1, 0, 0), infinity);
  if (in_plane.hit) {
    EXPECT_TRUE(in_plane.point.allFinite());
    EXPECT_NEAR(tree.closest_point(in_plane.point).distance_m, 0, 1e-15);
    EXPECT_NEAR(in_plane.normal.norm(), 1, 1e-15);
  }
  // A segment lying inside a face: its start is on the face.
  const SurfaceHit along = tree.first_hit_segment(Vector3d(-0.5 * h, 0, h), Vector3d(0.5 * h, 0, h));
  if (along.hit) {
    EXPECT_TRUE(along.point.allFinite());
  }
  // contains() on the cube: its faces are axis-aligned, the parity rays are not.
  EXPECT_TRUE(tree.contains(Vector3d(0, 0, 0)));
  EXPECT_TRUE(tree.contains(Vector3d(h * (1 - 1e-6), 0, 0)));
  EXPECT_FALSE(tree.contains(Vector3d(h, 0, 0)));
  EXPECT_FALSE(tree.contains(Vector3d(h, h, h)));
  EXPECT_FALSE(tree.contains(Vector3d(h * (1 + 1e-6), 0, 0)));
  // The closest point of the centre is at distance h (ties between all six faces).
  EXPECT_NEAR(tree.closest_point(Vector3d::Zero()).distance_m, h, 1e-15);
}

INSTANTIATE_TEST_SUITE_P(Volumes, Degenerate, ::testing::Values(BoundingVolume::obb, BoundingVolume::aabb),
                         [](const ::testing::TestParamInfo<BoundingVolume>& info) {
                           return info.param == BoundingVolume::obb ? "obb" : "aabb";
                         });

// ---------------------------------------------------------------------------------------------
// Counters, stats, settings.

TEST(BoundingVolumeHierarchy, CountersCountWhatTheDocumentationSays) {
  const Mesh mesh = geometry::icosphere(4, radius);
  for (const Configuration& configuration : configurations()) {
    const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles, configuration.settings);
    SCOPED_TRACE(configuration.name);
    // Far outside the root box: one box test, nothing else.
    QueryCounters counters;
    EXPECT_FALSE(tree.first_hit_segment(Vector3d(3 * radius, 0, 0), Vector3d(3 * radius, radius, 0), &counters).hit);
    EXPECT_EQ(counters.box_tests, 1);
    EXPECT_EQ(counters.triangle_tests, 0);
    EXPECT_EQ(counters.queries, 1);
    EXPECT_FALSE(tree.contains(Vector3d(3 * radius, 0, 0), &counters));
    EXPECT_EQ(counters.box_tests, 2);
    EXPECT_EQ(counters.queries, 2);

    // A tool-tip move through the surface: a leaf reached, at most a pair of boxes per level.
    const int depth = tree.stats().binary_depth;
    QueryCounters contact;
    const Vector3d direction = Vector3d(0.3, 0.2, 1).normalized();
    const SurfaceHit hit = tree.first_hit_segment(1.01 * radius * direction, 0.99 * radius * direction, &contact);
    ASSERT_TRUE(hit.hit);
    EXPECT_GE(contact.triangle_tests, 1);
    EXPECT_GE(contact.box_tests, depth);
    EXPECT_LE(contact.box_tests, 4 * depth);

    // The counting and non-counting paths give identical answers; counters accumulate.
    QueryMaker maker(mesh, 3);
    const Queries queries = maker.make(200, 200);
    QueryCounters all;
    for (std::size_t i = 0; i < queries.segments.size(); ++i) {
      const SurfaceHit a = tree.first_hit_segment(queries.segments[i].from, queries.segments[i].to);
      const SurfaceHit b = tree.first_hit_segment(queries.segments[i].from, queries.segments[i].to, &all);
      EXPECT_EQ(a.hit, b.hit);
      EXPECT_EQ(a.triangle, b.triangle);
      EXPECT_EQ(a.distance_m, b.distance_m);
      const ClosestSurfacePoint c = tree.closest_point(queries.points[i]);
      const ClosestSurfacePoint d = tree.closest_point(queries.points[i], &all);
      EXPECT_EQ(c.triangle, d.triangle);
      EXPECT_EQ(c.distance_m, d.distance_m);
      EXPECT_EQ(tree.contains(queries.contained[i]), tree.contains(queries.contained[i], &all));
    }
    EXPECT_EQ(all.queries, 600);
    EXPECT_GT(all.box_tests, 600);
    EXPECT_GT(all.triangle_tests, 400);
  }
}

TEST(BoundingVolumeHierarchy, EntryGridGivesTheAnswersOfATraversalFromTheRoot) {
  for (const Mesh& mesh : {geometry::icosphere(5, radius), torus(64, 24, 0.7 * radius, 0.25 * radius)}) {
    for (BoundingVolume volume : {BoundingVolume::obb, BoundingVolume::aabb}) {
      for (int width : {2, 4}) {
        BvhSettings settings;
        settings.bounding_volume = volume;
        settings.children_per_node = width;
        settings.entry_grid_cell = 0;
        const BoundingVolumeHierarchy root(mesh.vertices, mesh.triangles, settings);
        settings.entry_grid_cell = 2;
        const BoundingVolumeHierarchy grid(mesh.vertices, mesh.triangles, settings);
        const BvhStats stats = grid.stats();
        EXPECT_EQ(root.stats().entry_grid_cells, 0);
        EXPECT_GT(stats.entry_grid_cells, 0);
        // Cells of two mean edge lengths.
        double edges = 0;
        for (const Vector3i& t : mesh.triangles) {
          for (int k = 0; k < 3; ++k) edges += (mesh.vertices[t[(k + 1) % 3]] - mesh.vertices[t[k]]).norm();
        }
        EXPECT_NEAR(stats.entry_grid_cell_m, 2 * edges / (3.0 * mesh.triangles.size()), 1e-12);
        // Short moves everywhere near the surface, and moves in empty space.
        QueryMaker maker(mesh, 21);
        QueryCounters root_counters, grid_counters;
        for (int i = 0; i < 3000; ++i) {
          const Vector3d from = i % 4 == 0 ? maker.in_box(1.5) : maker.near_surface(0.6 * stats.entry_grid_cell_m);
          const Vector3d to = from + maker.uniform(0, 0.5) * stats.entry_grid_cell_m * maker.unit_vector();
          const SurfaceHit a = root.first_hit_segment(from, to, &root_counters);
          const SurfaceHit b = grid.first_hit_segment(from, to, &grid_counters);
          ASSERT_EQ(a.hit, b.hit) << "move " << i;
          EXPECT_EQ(a.triangle, b.triangle);
          EXPECT_EQ(a.distance_m, b.distance_m);
          const SurfaceHit c = root.first_hit_ray(from, to - from, (to - from).norm());
          const SurfaceHit d = grid.first_hit_ray(from, to - from, (to - from).norm());
          ASSERT_EQ(c.hit, d.hit) << "ray " << i;
          EXPECT_EQ(c.triangle, d.triangle);
        }
        EXPECT_LT(grid_counters.box_tests, root_counters.box_tests);
        // The same leaves are reachable, but a cover node's parts are not the tree's sibling
        // pairs, so the visiting order differs, and a hit found earlier or later prunes
        // different leaves: a small share of the triangle tests, far below the 3 % allowed.
        EXPECT_NEAR(static_cast<double>(grid_counters.triangle_tests), static_cast<double>(root_counters.triangle_tests),
                    0.03 * static_cast<double>(root_counters.triangle_tests));
      }
    }
  }
}

// The float box test of the AABB tree pads every box by the rounding of its inputs; 100 km
// from the origin that rounding is coarse (float's ulp there is 8e-3 m, about an edge
// here; without the pad this test fails) and the answers must still be brute force's. Beyond
// 1e15 m the double test takes over.
TEST(BoundingVolumeHierarchy, FloatBoxTestsPruneNoHitFarFromTheOrigin) {
  Mesh mesh = geometry::icosphere(3, radius);
  for (Vector3d& v : mesh.vertices) v += Vector3d(1e5, -7e4, 3e4);
  std::vector<BoundingVolumeHierarchy> trees;
  std::vector<std::string> names;
  for (int width : {2, 4}) {
    BvhSettings settings;
    settings.bounding_volume = BoundingVolume::aabb;
    settings.children_per_node = width;
    trees.emplace_back(mesh.vertices, mesh.triangles, settings);
    names.push_back("aabb width " + std::to_string(width));
  }
  std::vector<const BoundingVolumeHierarchy*> pointers;
  for (const BoundingVolumeHierarchy& tree : trees) pointers.push_back(&tree);
  // Segments and rays only: closest points use no float test, and their distances at 100 km
  // carry the coordinates' double rounding (1e-11 m), beyond the helper's tolerance.
  QueryMaker maker(mesh, 77);
  Queries queries = maker.make(1500, 150);
  queries.points.clear();
  queries.contained.clear();
  expect_brute_force_equality(mesh, pointers, names, queries, maker.scale());

  // Segments from just outside the surface through it to 1e14 m (float test, a large pad)
  // and 1e16 m (double test).
  const Vector3d centre = Vector3d(1e5, -7e4, 3e4);
  const Vector3d inward = Vector3d(-0.3, 0.5, -0.8).normalized();
  const Vector3d from = centre - 2 * radius * inward;
  for (const BoundingVolumeHierarchy& tree : trees) {
    for (double length : {1e14, 1e16}) {
      const Vector3d to = from + length * inward;
      const BruteHit expected = brute_first_hit(mesh, from, to - from, 1);
      const SurfaceHit hit = tree.first_hit_segment(from, to);
      ASSERT_TRUE(expected.hit);
      ASSERT_TRUE(hit.hit) << "to " << length << " m";
      EXPECT_EQ(hit.triangle, expected.triangle) << "to " << length << " m";
    }
  }
}

// The leaves' float pre-test may set a triangle aside only when the double test rejects it, so
// trees with and without it give the same answers to the bit. The segments cross the surface
// obliquely just inside and just outside every edge (down to 1e-12 of its length) and through
// its corners, where the edge functions are as small as the float test's rounding; points just
// inside and outside ask contains(), whose parity rays take the same test. The surface is also
// moved 1 km from the origin, where float's spacing (6e-5 m) is a few percent of an edge. (With
// the rounding bound set to zero, answers differ here: segments just inside an edge lose their
// hit.)
TEST(BoundingVolumeHierarchy, FloatLeafTestChangesNoAnswer) {
  struct Shape {
    BoundingVolume volume;
    int width, leaf;
  };
  // The default; leaves of 3 and 8 (part of a four-lane load, two loads); single triangles.
  const Shape shapes[] = {{BoundingVolume::aabb, 4, 4}, {BoundingVolume::obb, 4, 3},
                          {BoundingVolume::aabb, 2, 8}, {BoundingVolume::aabb, 4, 1}};
  for (const Vector3d& offset : {Vector3d(0, 0, 0), Vector3d(1e3, -700, 300)}) {
    Mesh mesh = perturbed_ellipsoid();
    for (Vector3d& v : mesh.vertices) v += offset;
    for (const Shape& shape : shapes) {
      BvhSettings settings;
      settings.bounding_volume = shape.volume;
      settings.children_per_node = shape.width;
      settings.max_leaf_triangles = shape.leaf;
      const BoundingVolumeHierarchy with_float(mesh.vertices, mesh.triangles, settings);
      settings.float_leaf_test = false;
      const BoundingVolumeHierarchy double_only(mesh.vertices, mesh.triangles, settings);
      int queries = 0, hits = 0;
      for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
        const Vector3d n = face_normal(mesh, t);
        for (int k = 0; k < 3; ++k) {
          const Vector3d& a = mesh.vertices[mesh.triangles[t][k]];
          const Vector3d& b = mesh.vertices[mesh.triangles[t][(k + 1) % 3]];
          const double length = (b - a).norm();
          const Vector3d along = (b - a) / length;
          const Vector3d inward = n.cross(along);  // in the plane, into the triangle
          const Vector3d direction = (n + 0.3 * along - 0.2 * inward).normalized();
          for (double s : {0.0, 1e-3, 0.5}) {
            for (double d : {0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-7, -1e-7, 1e-5, -1e-5, 1e-3, -1e-3}) {
              const Vector3d target = a + s * (b - a) + d * length * inward;
              const Vector3d from = target + 0.1 * length * direction;
              const Vector3d to = target - 0.1 * length * direction;
              const SurfaceHit expected = double_only.first_hit_segment(from, to);
              const SurfaceHit hit = with_float.first_hit_segment(from, to);
              ++queries;
              hits += expected.hit;
              ASSERT_EQ(hit.hit, expected.hit) << "triangle " << t << ", edge " << k << ", s " << s << ", d " << d
                                               << ", offset " << offset.transpose();
              ASSERT_EQ(hit.triangle, expected.triangle);
              ASSERT_EQ(hit.distance_m, expected.distance_m);
            }
          }
          // Inside/outside just off the edge's midpoint: the parity rays' leaves take the float test too.
          for (double e : {1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6, 1e-3, -1e-3}) {
            const Vector3d x = 0.5 * (a + b) + 1e-3 * length * inward + e * length * n;
            ASSERT_EQ(with_float.contains(x), double_only.contains(x))
                << "triangle " << t << ", edge " << k << ", e " << e << ", offset " << offset.transpose();
          }
        }
      }
      // Nearly every segment crosses the surface (only some just outside a silhouette miss).
      EXPECT_GT(hits, 9 * queries / 10);
    }
  }
}

TEST(BoundingVolumeHierarchy, EntryGridAnswersEmptyCellsWithoutTests) {
  const Mesh mesh = geometry::icosphere(4, radius);
  const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles);
  const double reach = tree.stats().entry_grid_cell_m / 2;
  ASSERT_GT(reach, 0);
  QueryCounters counters;
  // Far outside the grid, deep inside (empty cells), and a move just longer than the reach
  // (from the root: one box test).
  EXPECT_FALSE(tree.first_hit_segment(Vector3d(3 * radius, 0, 0), Vector3d(3 * radius, 0.5 * reach, 0), &counters).hit);
  EXPECT_FALSE(tree.first_hit_segment(Vector3d(0, 0, 0), Vector3d(0, 0, 0.5 * reach), &counters).hit);
  EXPECT_EQ(counters.box_tests, 0);
  EXPECT_EQ(counters.triangle_tests, 0);
  EXPECT_FALSE(tree.first_hit_segment(Vector3d(3 * radius, 0, 0), Vector3d(3 * radius, 1.01 * reach, 0), &counters).hit);
  EXPECT_EQ(counters.box_tests, 1);
  EXPECT_EQ(counters.queries, 3);
}

TEST(BoundingVolumeHierarchy, StatsDescribeABalancedTree) {
  const Mesh mesh = geometry::icosphere(4, radius);  // 5120 triangles
  for (int leaf : {1, 2, 4, 8}) {
    for (int width : {2, 4}) {
      BvhSettings settings;
      settings.max_leaf_triangles = leaf;
      settings.children_per_node = width;
      const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles, settings);
      const BvhStats stats = tree.stats();
      EXPECT_EQ(stats.triangle_count, 5120);
      EXPECT_LE(stats.max_leaf_size, leaf);
      EXPECT_GE(stats.leaf_count, 5120 / leaf);
      // Median splits: ⌈log2(n / leaf)⌉ + 1 binary levels; a 4-wide node spans two of them.
      const int binary_depth = static_cast<int>(std::ceil(std::log2(5120.0 / leaf))) + 1;
      EXPECT_EQ(stats.binary_depth, binary_depth) << "leaf " << leaf;
      if (width == 2) {
        EXPECT_EQ(stats.node_count, 2 * stats.leaf_count - 1);
        EXPECT_EQ(stats.depth, binary_depth);
      } else {
        EXPECT_LT(stats.node_count, 2 * stats.leaf_count - 1);
        EXPECT_EQ(stats.depth, binary_depth / 2 + 1);
      }
      EXPECT_GT(stats.memory_bytes, static_cast<std::size_t>(stats.node_count) * 64);
    }
  }
}

TEST(BoundingVolumeHierarchy, SettingsAndSurfacesAreValidated) {
  BvhSettings settings;
  EXPECT_NO_THROW(settings.validate());
  settings.max_leaf_triangles = 0;
  try {
    settings.validate();
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("max_leaf_triangles"), std::string::npos);
  }
  settings.max_leaf_triangles = 65;
  EXPECT_THROW(settings.validate(), std::invalid_argument);
  settings = {};
  settings.bounding_volume = static_cast<BoundingVolume>(7);
  EXPECT_THROW(settings.validate(), std::invalid_argument);
  settings = {};
  settings.children_per_node = 3;
  EXPECT_THROW(settings.validate(), std::invalid_argument);
  settings = {};
  for (double cell : {-1.0, 0.1, nan, infinity}) {
    settings.entry_grid_cell = cell;
    try {
      settings.validate();
      FAIL() << cell;
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("entry_grid_cell"), std::string::npos);
    }
  }

  const Mesh mesh = geometry::icosphere(1, radius);
  settings = {};
  settings.max_leaf_triangles = -1;
  EXPECT_THROW(BoundingVolumeHierarchy(mesh.vertices, mesh.triangles, settings), std::invalid_argument);
  Mesh holed = mesh;
  holed.triangles.pop_back();
  try {
    BoundingVolumeHierarchy tree(holed.vertices, holed.triangles, {}, "holed sphere");
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("holed sphere"), std::string::npos) << error.what();
  }
}

TEST(BoundingVolumeHierarchy, ConcurrentReadersGetTheSerialAnswers) {
  const Mesh mesh = geometry::icosphere(4, radius);
  const BoundingVolumeHierarchy tree(mesh.vertices, mesh.triangles);
  QueryMaker maker(mesh, 11);
  const Queries queries = maker.make(2000, 0);
  std::vector<double> serial;
  for (const SegmentQuery& s : queries.segments) serial.push_back(tree.first_hit_segment(s.from, s.to).distance_m);
  std::array<int, 2> mismatches{};
  std::array<std::thread, 2> threads;
  for (int k = 0; k < 2; ++k) {
    threads[k] = std::thread([&, k] {
      for (int repeat = 0; repeat < 5; ++repeat) {
        for (std::size_t i = 0; i < queries.segments.size(); ++i) {
          QueryCounters counters;
          const SurfaceHit hit = tree.first_hit_segment(queries.segments[i].from, queries.segments[i].to, &counters);
          mismatches[k] += hit.distance_m != serial[i];
        }
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(mismatches[0] + mismatches[1], 0);
}

}  // namespace
}  // namespace touchstone::realtime::collision
