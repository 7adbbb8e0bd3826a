// TriangleSurface: areas and volumes converging to the exact ones, closest point and inside
// tests against brute force (a different route than the implementation) on spheres, a torus and
// gmsh's benchmark surfaces, sharp edges and corners, and broken surfaces refused by name.
#include "support/temporary_directory.hpp"
#include "support/expect_invalid_argument.hpp"
#include "support/test_surfaces.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/msh_reader.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

namespace touchstone::geometry {
namespace {

using touchstone::testing::TemporaryDirectory;
using touchstone::testing::expect_invalid_argument;
using touchstone::testing::torus;

using Eigen::Vector3d;
using Eigen::Vector3i;

constexpr double pi = 3.14159265358979323846;

using Mesh = TriangleMeshData;

/// Latitude–longitude sphere: poles with fans of `around` triangles.
Mesh uv_sphere(int around, int rings, double radius) {
  Mesh mesh;
  mesh.vertices.push_back({0, 0, radius});
  for (int i = 1; i < rings; ++i) {
    const double polar = pi * i / rings;
    for (int j = 0; j < around; ++j) {
      const double azimuth = 2 * pi * j / around;
      mesh.vertices.push_back(radius * Vector3d(std::sin(polar) * std::cos(azimuth),
                                                std::sin(polar) * std::sin(azimuth), std::cos(polar)));
    }
  }
  mesh.vertices.push_back({0, 0, -radius});
  const int south = static_cast<int>(mesh.vertices.size()) - 1;
  const auto ring = [&](int i, int j) { return 1 + (i - 1) * around + (j % around); };
  for (int j = 0; j < around; ++j) {
    mesh.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
    mesh.triangles.push_back({south, ring(rings - 1, j + 1), ring(rings - 1, j)});
    for (int i = 1; i + 1 < rings; ++i) {
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  }
  return mesh;
}

TriangleSurface make(const Mesh& mesh, const std::string& source = "test surface") {
  return TriangleSurface(mesh.vertices, mesh.triangles, source);
}

// ---------------------------------------------------------------------------------------------
// Brute force, by a different route than the implementation: project onto the plane, keep the
// projection when it falls inside, otherwise take the nearest of the three edges.

Vector3d closest_on_segment(const Vector3d& x, const Vector3d& a, const Vector3d& b) {
  const Vector3d d = b - a;
  const double s = std::clamp((x - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return a + s * d;
}

Vector3d closest_on_triangle_brute(const Vector3d& x, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d n = (b - a).cross(c - a);
  const Vector3d in_plane = x - n * ((x - a).dot(n) / n.squaredNorm());
  const bool inside = (b - a).cross(in_plane - a).dot(n) >= 0 && (c - b).cross(in_plane - b).dot(n) >= 0 &&
                      (a - c).cross(in_plane - c).dot(n) >= 0;
  if (inside) return in_plane;
  Vector3d best = closest_on_segment(x, a, b);
  for (const Vector3d& q : {closest_on_segment(x, b, c), closest_on_segment(x, c, a)}) {
    if ((q - x).squaredNorm() < (best - x).squaredNorm()) best = q;
  }
  return best;
}

struct Brute {
  Vector3d point;
  double distance;
};

Brute brute_closest(const TriangleSurface& surface, const Vector3d& x) {
  Brute best{Vector3d::Zero(), std::numeric_limits<double>::infinity()};
  for (const Vector3i& t : surface.triangles()) {
    const Vector3d q = closest_on_triangle_brute(x, surface.vertices()[t[0]], surface.vertices()[t[1]],
                                                 surface.vertices()[t[2]]);
    const double d = (q - x).norm();
    if (d < best.distance) best = {q, d};
  }
  return best;
}

double distance_to_triangle(const TriangleSurface& surface, int triangle, const Vector3d& x) {
  const Vector3i& t = surface.triangles()[triangle];
  return (closest_on_triangle_brute(x, surface.vertices()[t[0]], surface.vertices()[t[1]], surface.vertices()[t[2]]) - x)
      .norm();
}

/// Generalised winding number (solid angles, van Oosterom & Strackee): 1 inside, 0 outside.
double winding_number(const TriangleSurface& surface, const Vector3d& x) {
  double sum = 0;
  for (const Vector3i& t : surface.triangles()) {
    const Vector3d a = surface.vertices()[t[0]] - x;
    const Vector3d b = surface.vertices()[t[1]] - x;
    const Vector3d c = surface.vertices()[t[2]] - x;
    const double la = a.norm();
    const double lb = b.norm();
    const double lc = c.norm();
    sum += 2 * std::atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la);
  }
  return sum / (4 * pi);
}

// ---------------------------------------------------------------------------------------------
// Query points: uniform in the enlarged bounding box, just off the faces, around vertices and
// edges, and exactly on vertices and edge midpoints.

struct Box {
  Vector3d lower, upper;
  double diagonal() const { return (upper - lower).norm(); }
};

Box bounding_box(const TriangleSurface& surface) {
  Box box{surface.vertices()[0], surface.vertices()[0]};
  for (const Vector3d& v : surface.vertices()) {
    box.lower = box.lower.cwiseMin(v);
    box.upper = box.upper.cwiseMax(v);
  }
  return box;
}

std::vector<Vector3d> query_points(const TriangleSurface& surface, int count, unsigned seed) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(surface.triangles().size()) - 1);
  const Box box = bounding_box(surface);
  const double scale = box.diagonal();
  const Vector3d centre = 0.5 * (box.lower + box.upper);
  const auto random_direction = [&] {
    const double z = 2 * unit(random) - 1;
    const double phi = 2 * pi * unit(random);
    const double s = std::sqrt(1 - z * z);
    return Vector3d(s * std::cos(phi), s * std::sin(phi), z);
  };
  // Log-uniform offsets from 1e-8 to 1e-2 of the size: "very near" down to a few nanometres.
  const auto small_offset = [&] { return scale * std::pow(10.0, -8 + 6 * unit(random)); };

  std::vector<Vector3d> points;
  for (int i = 0; i < count; ++i) {
    Vector3d x;
    for (int k = 0; k < 3; ++k) x[k] = centre[k] + 0.75 * (box.upper[k] - box.lower[k]) * (2 * unit(random) - 1);
    points.push_back(x);
  }
  for (int i = 0; i < count; ++i) {
    const Vector3i& t = surface.triangles()[pick(random)];
    double u = unit(random);
    double v = unit(random);
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Vector3d& a = surface.vertices()[t[0]];
    const Vector3d& b = surface.vertices()[t[1]];
    const Vector3d& c = surface.vertices()[t[2]];
    const Vector3d on_face = a + u * (b - a) + v * (c - a);
    const Vector3d normal = (b - a).cross(c - a).normalized();
    points.push_back(on_face + (unit(random) < 0.5 ? -1 : 1) * small_offset() * normal);
  }
  for (int i = 0; i < count / 2; ++i) {
    const Vector3i& t = surface.triangles()[pick(random)];
    const int k = i % 3;
    const Vector3d& a = surface.vertices()[t[k]];
    const Vector3d& b = surface.vertices()[t[(k + 1) % 3]];
    const Vector3d feature = (i % 2 == 0) ? a : Vector3d(a + unit(random) * (b - a));
    points.push_back(feature + small_offset() * random_direction());
  }
  return points;
}

/// Compares project/contains/signed_distance with brute force; returns how many points were
/// compared for containment (the others lie within 1e-9 m of the surface).
int check_against_brute_force(const TriangleSurface& surface, const std::vector<Vector3d>& points) {
  const double scale = bounding_box(surface).diagonal();
  int ties = 0;
  int compared = 0;
  for (const Vector3d& x : points) {
    const SurfaceProjection p = surface.project(x);
    const Brute brute = brute_closest(surface, x);
    SCOPED_TRACE("x = (" + std::to_string(x[0]) + ", " + std::to_string(x[1]) + ", " + std::to_string(x[2]) + ")");
    EXPECT_GE(p.triangle, 0);
    if (p.triangle < 0) continue;
    // Both distances carry rounding of order eps × size, hence the absolute floor.
    const double tolerance = 1e-12 * brute.distance + 1e-14 * scale;
    EXPECT_NEAR(p.distance_m, brute.distance, tolerance);
    EXPECT_NEAR((p.point - x).norm(), p.distance_m, tolerance);
    EXPECT_NEAR(distance_to_triangle(surface, p.triangle, x), brute.distance, tolerance);
    EXPECT_NEAR(p.normal.norm(), 1.0, 1e-12);
    // The same closest point, unless two distinct surface points are (to rounding) equally near.
    if ((p.point - brute.point).norm() > 1e-9 * scale) ++ties;

    const bool inside = surface.contains(x);
    const double signed_distance = surface.signed_distance(x);
    EXPECT_EQ(signed_distance, inside ? -p.distance_m : p.distance_m);
    if (brute.distance > 1e-9) {
      ++compared;
      const double winding = winding_number(surface, x);
      EXPECT_EQ(inside, winding > 0.5) << "winding number " << winding << ", distance " << brute.distance;
    }
  }
  EXPECT_LE(ties, static_cast<int>(points.size()) / 1000 + 1);
  return compared;
}

/// Vertices project onto themselves exactly; edge midpoints onto themselves to rounding.
void check_points_on_surface(const TriangleSurface& surface) {
  const double scale = bounding_box(surface).diagonal();
  for (std::size_t v = 0; v < surface.vertices().size(); v += 7) {
    const Vector3d& x = surface.vertices()[v];
    const SurfaceProjection p = surface.project(x);
    EXPECT_EQ(p.distance_m, 0.0);
    EXPECT_EQ(p.point, x);
    EXPECT_NEAR((p.normal - surface.vertex_normals()[v]).norm(), 0, 1e-12) << "vertex " << v;
    EXPECT_TRUE(surface.contains(x));
    EXPECT_EQ(surface.signed_distance(x), 0.0);
  }
  for (std::size_t t = 0; t < surface.triangles().size(); t += 5) {
    const Vector3i& triangle = surface.triangles()[t];
    const Vector3d x = 0.5 * (surface.vertices()[triangle[0]] + surface.vertices()[triangle[1]]);
    const SurfaceProjection p = surface.project(x);
    EXPECT_LE(p.distance_m, 1e-15 * scale);
    EXPECT_LE((p.point - x).norm(), 1e-15 * scale);
    EXPECT_LE(std::abs(surface.signed_distance(x)), 1e-15 * scale);
  }
}

// ---------------------------------------------------------------------------------------------
// Temporary files.

/// The B1/B2 benchmark surface written by touchstone::meshes (generated once per test program).
const std::string& benchmark_mesh(meshes::Benchmark benchmark) {
  static const TemporaryDirectory directory("triangle_surface");
  static std::map<meshes::Benchmark, std::string> paths;
  auto found = paths.find(benchmark);
  if (found == paths.end()) {
    meshes::MeshParameters parameters;
    parameters.benchmark = benchmark;
    const std::string path = directory.path(meshes::to_string(benchmark) + ".msh");
    meshes::generate_mesh(parameters, path);
    found = paths.emplace(benchmark, path).first;
  }
  return found->second;
}

// ---------------------------------------------------------------------------------------------

TEST(TriangleSurface, IcosphereAreaAndVolumeLieBetweenInscribedAndCircumscribedSpheres) {
  const double radius = 0.03;
  const Mesh mesh = icosphere(3, radius);
  const TriangleSurface surface = make(mesh);
  // The polyhedron lies between its insphere (nearest face plane) and the sphere: both are
  // convex, so area and volume are bracketed by those of the two balls.
  double inner = radius;
  for (const Vector3i& t : mesh.triangles) {
    const Vector3d& a = mesh.vertices[t[0]];
    const Vector3d n = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).normalized();
    inner = std::min(inner, a.dot(n));
  }
  EXPECT_GT(inner, 0.99 * radius);
  EXPECT_LT(surface.area_m2(), 4 * pi * radius * radius);
  EXPECT_GT(surface.area_m2(), 4 * pi * inner * inner);
  EXPECT_LT(surface.volume_m3(), 4 * pi * std::pow(radius, 3) / 3);
  EXPECT_GT(surface.volume_m3(), 4 * pi * std::pow(inner, 3) / 3);

  // The same sums computed here, about the origin rather than the box centre.
  double area = 0;
  double volume = 0;
  for (const Vector3i& t : mesh.triangles) {
    const Vector3d& a = mesh.vertices[t[0]];
    const Vector3d& b = mesh.vertices[t[1]];
    const Vector3d& c = mesh.vertices[t[2]];
    area += 0.5 * (b - a).cross(c - a).norm();
    volume += a.dot(b.cross(c)) / 6;
  }
  EXPECT_NEAR(surface.area_m2(), area, 1e-12 * area);
  EXPECT_NEAR(surface.volume_m3(), volume, 1e-12 * volume);

  // Sphere vertex normals are radial up to the discretisation.
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    EXPECT_GT(surface.vertex_normals()[v].dot(mesh.vertices[v].normalized()), 0.999);
  }
}

TEST(TriangleSurface, UvSphereAndTorusAreasAndVolumesConverge) {
  const double radius = 2.0;
  const TriangleSurface sphere = make(uv_sphere(64, 32, radius));
  EXPECT_NEAR(sphere.area_m2() / (4 * pi * radius * radius), 1, 5e-3);
  EXPECT_NEAR(sphere.volume_m3() / (4 * pi * std::pow(radius, 3) / 3), 1, 5e-3);

  const double major = 1.0;
  const double minor = 0.3;
  const double area = 4 * pi * pi * major * minor;
  const double volume = 2 * pi * pi * major * minor * minor;
  double previous_area_error = 1;
  double previous_volume_error = 1;
  for (const int n : {16, 32, 64}) {
    const TriangleSurface surface = make(torus(2 * n, n, major, minor));
    const double area_error = std::abs(surface.area_m2() / area - 1);
    const double volume_error = std::abs(surface.volume_m3() / volume - 1);
    // Second order: halving h divides the error by about 4.
    EXPECT_LT(area_error, previous_area_error / 3.5) << n;
    EXPECT_LT(volume_error, previous_volume_error / 3.5) << n;
    previous_area_error = area_error;
    previous_volume_error = volume_error;
  }
  EXPECT_LT(previous_area_error, 3e-3);
  EXPECT_LT(previous_volume_error, 3e-3);
}

TEST(TriangleSurface, IcosphereQueriesMatchBruteForce) {
  const double radius = 0.04;
  const Mesh mesh = icosphere(3, radius);
  const TriangleSurface surface = make(mesh);
  const std::vector<Vector3d> points = query_points(surface, 1500, 1);
  EXPECT_GT(check_against_brute_force(surface, points), 3000);
  check_points_on_surface(surface);

  // Against the exact sphere: the surface lies between radius r_in and R, so
  // |x| − R ≤ signed distance ≤ |x| − r_in.
  const double inner = radius * std::cos(0.2);  // generous: level 3 faces subtend < 0.1 rad
  for (const Vector3d& x : points) {
    const double d = surface.signed_distance(x);
    EXPECT_GE(d, x.norm() - radius - 1e-15);
    EXPECT_LE(d, x.norm() - inner);
  }
}

// The local surface fit of the MFS gathers the vertices near the contact this way on every model
// build, so it must find exactly the vertices a scan of all of them finds, in the same order.
TEST(TriangleSurface, VerticesWithinABallMatchAScanOfEveryVertex) {
  const double radius = 0.04;
  const Mesh mesh = icosphere(4, radius);
  const TriangleSurface surface = make(mesh);
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> coordinate(-1.5 * radius, 1.5 * radius);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int nonempty = 0;
  for (int i = 0; i < 400; ++i) {
    // Centres anywhere, or on a vertex (whose own distance is exactly zero).
    const Vector3d centre = i % 4 == 0 ? mesh.vertices[static_cast<std::size_t>(i) % mesh.vertices.size()]
                                       : Vector3d(coordinate(random), coordinate(random), coordinate(random));
    // Radii from nothing to beyond the whole sphere.
    const double reach = i % 5 == 0 ? 0.0 : 3 * radius * unit(random) * unit(random);
    std::vector<int> expected;
    for (int v = 0; v < static_cast<int>(mesh.vertices.size()); ++v) {
      if ((mesh.vertices[static_cast<std::size_t>(v)] - centre).squaredNorm() <= reach * reach) expected.push_back(v);
    }
    ASSERT_EQ(surface.vertices_within(centre, reach), expected) << "ball " << i << ", radius " << reach;
    nonempty += !expected.empty();
  }
  EXPECT_GT(nonempty, 150);
  EXPECT_EQ(surface.vertices_within(Vector3d::Zero(), 10 * radius).size(), mesh.vertices.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(surface.vertices_within(Vector3d(nan, 0, 0), radius).empty());
  EXPECT_TRUE(surface.vertices_within(Vector3d::Zero(), -1.0).empty());
  EXPECT_TRUE(surface.vertices_within(Vector3d::Zero(), nan).empty());
}

TEST(TriangleSurface, UvSphereAndTorusQueriesMatchBruteForce) {
  const TriangleSurface sphere = make(uv_sphere(24, 12, 1.0));
  EXPECT_GT(check_against_brute_force(sphere, query_points(sphere, 800, 2)), 1600);
  check_points_on_surface(sphere);
  // The poles: fans of 24 triangles; the angle-weighted normal is the axis.
  EXPECT_NEAR((sphere.project({0, 0, 1.5}).normal - Vector3d::UnitZ()).norm(), 0, 1e-12);
  EXPECT_TRUE(sphere.contains({0, 0, 0.999}));
  EXPECT_FALSE(sphere.contains({0, 0, 1.001}));

  const TriangleSurface ring = make(torus(48, 24, 1.0, 0.3));
  EXPECT_GT(check_against_brute_force(ring, query_points(ring, 800, 3)), 1600);
  check_points_on_surface(ring);
  // The hole of the torus is outside; the tube is inside.
  EXPECT_FALSE(ring.contains({0, 0, 0}));
  EXPECT_TRUE(ring.contains({1, 0, 0}));
  EXPECT_NEAR(ring.signed_distance({0, 0, 0}), 0.7, 0.01);
}

TEST(TriangleSurface, HemisphereFromGmshMatchesExactValuesAndBruteForce) {
  const std::string& path = benchmark_mesh(meshes::Benchmark::B2);
  const TriangleSurface all = meshes::load_msh_surface(path);
  const TriangleSurface named = meshes::load_msh_surface(path, {"base", "tool_patch", "free"});
  EXPECT_EQ(all.triangles().size(), named.triangles().size());
  EXPECT_EQ(all.vertices().size(), named.vertices().size());
  EXPECT_EQ(all.area_m2(), named.area_m2());

  // The facets are inscribed in the hemisphere (vertices on it): a little less area and
  // volume, by O((h/R)²) with h the longest edge.
  const double radius = meshes::MeshParameters{}.body_radius_m;
  double longest = 0;
  for (const Vector3i& t : named.triangles()) {
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (named.vertices()[t[k]] - named.vertices()[t[(k + 1) % 3]]).norm());
    }
  }
  const double tolerance = std::pow(longest / radius, 2);
  const double area = 3 * pi * radius * radius;
  const double volume = 2 * pi * std::pow(radius, 3) / 3;
  EXPECT_LT(named.area_m2(), area);
  EXPECT_LT(named.volume_m3(), volume);
  EXPECT_GT(named.area_m2(), area * (1 - tolerance));
  EXPECT_GT(named.volume_m3(), volume * (1 - tolerance));

  EXPECT_GT(check_against_brute_force(named, query_points(named, 1200, 4)), 2400);
  check_points_on_surface(named);
  // The rim (base circle) is a sharp 90° edge: just outside and just inside of it.
  EXPECT_FALSE(named.contains({radius * 0.999, 0, -1e-6}));
  EXPECT_TRUE(named.contains({radius * 0.99, 0, 1e-6}));
  EXPECT_NEAR(named.project({0, 0, 2 * radius}).normal.z(), 1, 1e-3);
  EXPECT_NEAR(named.project({0, 0, -radius}).normal.z(), -1, 1e-12);
}

TEST(TriangleSurface, CylinderFromGmshHasSharpEdgesHandled) {
  const TriangleSurface surface = meshes::load_msh_surface(benchmark_mesh(meshes::Benchmark::B1));
  const double w = meshes::MeshParameters{}.body_radius_m;
  EXPECT_NEAR(surface.volume_m3() / (pi * w * w * w), 1, 0.01);
  EXPECT_NEAR(surface.area_m2() / (4 * pi * w * w), 1, 0.01);
  EXPECT_GT(check_against_brute_force(surface, query_points(surface, 600, 5)), 1200);
  check_points_on_surface(surface);
}

TEST(TriangleSurface, CubeCornersUseAngleWeightedNormals) {
  // [-1, 1]³, each face split along one diagonal: at a corner, one face contributes one
  // triangle and another two, yet each face subtends π/2, so the normal is the diagonal.
  std::vector<Vector3d> vertices;
  for (int i = 0; i < 8; ++i) vertices.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1);
  const std::vector<Vector3i> triangles{{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                        {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  const TriangleSurface cube(vertices, triangles, "cube");
  EXPECT_NEAR(cube.area_m2(), 24, 1e-13);
  EXPECT_NEAR(cube.volume_m3(), 8, 1e-13);
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    EXPECT_NEAR((cube.vertex_normals()[v] - vertices[v] / std::sqrt(3.0)).norm(), 0, 1e-15) << v;
  }
  // On an edge the pseudo-normal bisects the two faces.
  const SurfaceProjection edge = cube.project({2, 0, 2});
  EXPECT_NEAR((edge.point - Vector3d(1, 0, 1)).norm(), 0, 1e-15);
  EXPECT_NEAR((edge.normal - Vector3d(1, 0, 1) / std::sqrt(2.0)).norm(), 0, 1e-15);
  EXPECT_GT(check_against_brute_force(cube, query_points(cube, 1000, 6)), 2000);
  check_points_on_surface(cube);
}

TEST(TriangleSurface, NonFiniteAndFarQueriesDoNotCrash) {
  const TriangleSurface surface = make(icosphere(1, 1.0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const SurfaceProjection p = surface.project({nan, 0, 0});
  EXPECT_EQ(p.triangle, -1);
  EXPECT_TRUE(std::isnan(p.distance_m));
  EXPECT_FALSE(surface.contains({0, nan, 0}));
  EXPECT_TRUE(std::isnan(surface.signed_distance({0, 0, nan})));
  EXPECT_FALSE(surface.contains({1e300, 1e300, 1e300}));
  EXPECT_GT(surface.signed_distance({1e300, 0, 0}), 0);
  EXPECT_NEAR(surface.signed_distance({1e6, 0, 0}), 1e6 - 1, 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Broken surfaces.

TEST(TriangleSurface, RejectsBrokenSurfacesNamingTheProblem) {
  const Mesh good = icosphere(1, 1.0);
  ASSERT_NO_THROW(make(good));

  Mesh hole = good;
  hole.triangles.erase(hole.triangles.begin() + 17);
  expect_invalid_argument([&] { make(hole, "liver.obj"); }, {"liver.obj", "hole", "edge ("});

  Mesh flipped = good;
  std::swap(flipped.triangles[23][0], flipped.triangles[23][1]);
  expect_invalid_argument([&] { make(flipped, "liver.obj"); }, {"liver.obj", "triangle 23", "orientation"});

  Mesh duplicate = good;
  duplicate.triangles.push_back(good.triangles[5]);
  expect_invalid_argument([&] { make(duplicate); }, {"test surface", "triangle 5", "triangle 80", "duplicate"});

  Mesh reversed_duplicate = good;
  reversed_duplicate.triangles.push_back({good.triangles[5][1], good.triangles[5][0], good.triangles[5][2]});
  expect_invalid_argument([&] { make(reversed_duplicate); }, {"triangle 5", "duplicate"});

  // A fin: a third triangle on the edge of triangle 0.
  Mesh fin = good;
  fin.vertices.push_back({3, 3, 3});
  fin.triangles.push_back({good.triangles[0][0], good.triangles[0][1], static_cast<int>(good.vertices.size())});
  expect_invalid_argument([&] { make(fin); }, {"non-manifold", "3 triangles", "triangle 0", "triangle 80"});

  Mesh not_a_number = good;
  not_a_number.vertices[11].y() = std::numeric_limits<double>::quiet_NaN();
  expect_invalid_argument([&] { make(not_a_number); }, {"vertex 11", "non-finite"});

  Mesh infinite = good;
  infinite.vertices[3].z() = std::numeric_limits<double>::infinity();
  expect_invalid_argument([&] { make(infinite); }, {"vertex 3", "non-finite"});

  Mesh out_of_range = good;
  out_of_range.triangles[9][2] = 42;
  expect_invalid_argument([&] { make(out_of_range); }, {"triangle 9", "vertex 42", "out of range"});
  out_of_range.triangles[9][2] = -1;
  expect_invalid_argument([&] { make(out_of_range); }, {"triangle 9", "vertex -1", "out of range"});

  expect_invalid_argument([&] { TriangleSurface({}, {}, "nothing.msh"); }, {"nothing.msh", "no triangles"});
  expect_invalid_argument([&] { TriangleSurface(good.vertices, {}, "nothing.msh"); }, {"no triangles"});

  Mesh inward = good;
  for (Vector3i& t : inward.triangles) std::swap(t[1], t[2]);
  expect_invalid_argument([&] { make(inward); }, {"non-positive volume", "inward"});

  Mesh repeated = good;
  repeated.triangles[4][1] = repeated.triangles[4][0];
  expect_invalid_argument([&] { make(repeated); }, {"triangle 4", "degenerate"});
}

TEST(TriangleSurface, RejectsDegenerateAndPinchedSurfaces) {
  std::vector<Vector3d> vertices{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::vector<Vector3i> triangles{{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                  {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  const TriangleSurface octahedron(vertices, triangles);
  EXPECT_NEAR(octahedron.volume_m3(), 4.0 / 3, 1e-15);
  EXPECT_NEAR(octahedron.area_m2(), 4 * std::sqrt(3.0), 1e-14);

  // Face 0 split into a fan around a new vertex placed on its edge 0–2: still closed and
  // consistently oriented, but the part (0, 2, 6) has zero area.
  vertices.push_back(0.5 * (vertices[0] + vertices[2]));
  triangles[0] = {0, 2, 6};
  triangles.push_back({2, 4, 6});
  triangles.push_back({4, 0, 6});
  expect_invalid_argument([&] { TriangleSurface(vertices, triangles, "split.msh"); }, {"split.msh", "triangle 0", "degenerate"});
  vertices[6] = (vertices[0] + vertices[2] + vertices[4]) / 3;
  EXPECT_NO_THROW(TriangleSurface(vertices, triangles));

  // Two tetrahedra sharing one vertex: every edge is fine, the vertex is not.
  const std::vector<Vector3d> pinched{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  const std::vector<Vector3i> faces{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3},
                                    {0, 4, 5}, {0, 6, 4}, {0, 5, 6}, {4, 6, 5}};
  EXPECT_NO_THROW(TriangleSurface(pinched, {faces.begin(), faces.begin() + 4}));
  expect_invalid_argument([&] { TriangleSurface(pinched, faces, "pinched"); }, {"pinched", "vertex 0", "non-manifold"});
}

}  // namespace
}  // namespace touchstone::geometry
