// Collision detection (paper Table 1; target at 35K triangles: ≤ 0.5 µs and ≤ 16 box tests per
// query, within 3× of Embree in the same run): the first-contact segment query — a tool-tip
// move of 0.1–1 mm crossing the surface — on spheres of about 500, 2.5K, 17K and 35K
// triangles (the paper's sizes), through the own OBB and AABB trees (width 4 or 2, leaves of
// 1–8 triangles, entry grid cells of 0–4 mean edges) and through Embree (float, rtcIntersect1)
// in the same run — random moves all over the surface (cold caches: the worst case) and the
// same moves in spatial order (warm caches, as in a haptic loop); closest point; contains();
// build and refit.
//
// Counters, per query, from one counting pass over the same queries: box_tests (every
// bounding-volume test, as BoundingVolumeHierarchy documents), triangle_tests, and for the
// binary tree without grid (the paper's structure) descents = (box_tests − 1) / 2, the inner
// nodes entered — what a count of one test per level would report.
//
//   ./build/release/benchmarks/collision_benchmark --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// TOUCHSTONE_ORGAN_MESH_DIR: every *.msh file there (a gmsh surface) is benchmarked too.
#include "support/embree_scene.hpp"
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/msh_reader.hpp"

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace {

using touchstone::testing::EmbreeScene;

using Eigen::Vector3d;
using Eigen::Vector3i;
using touchstone::realtime::collision::BoundingVolume;
using touchstone::realtime::collision::BoundingVolumeHierarchy;
using touchstone::realtime::collision::BvhSettings;
using touchstone::realtime::collision::QueryCounters;
using touchstone::realtime::collision::SurfaceHit;
using touchstone::geometry::TriangleSurface;

constexpr double radius_m = 0.05;
constexpr int query_count = 4096;  // a power of two: the loops cycle with a mask

/// Geodesic sphere: each icosahedron face cut into f² triangles, projected onto the sphere:
/// 20 f² triangles (f = 5, 11, 29, 42 give 500, 2420, 16820, 35280).
TriangleSurface geodesic_sphere(int frequency, double radius) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  const std::vector<Vector3d> corners = {{-1, g, 0}, {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
                                         {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  const std::vector<Vector3i> faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},  {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},  {9, 8, 1}};
  // A lattice point of a face is i·a + j·b + k·c over f with i + j + k = f; points on shared
  // edges are the same combination of the same corners, so the sorted (corner, weight) pairs
  // identify them exactly.
  std::map<std::vector<std::pair<int, int>>, int> index_of;
  std::vector<Vector3d> vertices;
  const auto vertex = [&](const Vector3i& face, int i, int j, int k) {
    std::vector<std::pair<int, int>> key;
    for (const auto& [corner, weight] : {std::pair{face[0], i}, std::pair{face[1], j}, std::pair{face[2], k}}) {
      if (weight > 0) key.emplace_back(corner, weight);
    }
    std::sort(key.begin(), key.end());
    const auto found = index_of.find(key);
    if (found != index_of.end()) return found->second;
    Vector3d p = Vector3d::Zero();
    for (const auto& [corner, weight] : key) p += weight * corners[corner];
    vertices.push_back(radius * p.normalized());
    return index_of[key] = static_cast<int>(vertices.size()) - 1;
  };
  std::vector<Vector3i> triangles;
  for (const Vector3i& face : faces) {
    for (int j = 0; j < frequency; ++j) {
      for (int k = 0; j + k < frequency; ++k) {
        const int i = frequency - j - k;
        triangles.emplace_back(vertex(face, i, j, k), vertex(face, i - 1, j + 1, k), vertex(face, i - 1, j, k + 1));
        if (j + k + 1 < frequency) {
          triangles.emplace_back(vertex(face, i - 1, j + 1, k), vertex(face, i - 2, j + 1, k + 1),
                                 vertex(face, i - 1, j, k + 1));
        }
      }
    }
  }
  return TriangleSurface(std::move(vertices), std::move(triangles), "geodesic sphere f=" + std::to_string(frequency));
}


struct Segment {
  Vector3d from, to;
};

/// A surface with its fixed-seed queries and the trees built on demand.
class Scene {
 public:
  explicit Scene(TriangleSurface surface) : surface_(std::move(surface)) {
    const auto& vertices = surface_.vertices();
    const auto& triangles = surface_.triangles();
    Vector3d lower = vertices[0], upper = vertices[0];
    for (const Vector3d& v : vertices) {
      lower = lower.cwiseMin(v);
      upper = upper.cwiseMax(v);
    }
    // Millimetres as at the paper's 10 cm organ, scaled to this surface's size.
    const double mm = (upper - lower).maxCoeff() / 0.1 * 1e-3;
    std::mt19937_64 random(2002);
    std::uniform_real_distribution<double> unit(0, 1);
    std::normal_distribution<double> normal;
    std::uniform_int_distribution<int> pick(0, static_cast<int>(triangles.size()) - 1);
    for (int i = 0; i < query_count; ++i) {
      // A point on a random triangle; the tool moves through it from outside, within 60° of
      // the inward normal, 0.1–1 mm per cycle, crossing at a random fraction of the move.
      const Vector3i& t = triangles[pick(random)];
      double u = unit(random), v = unit(random);
      if (u + v > 1) {
        u = 1 - u;
        v = 1 - v;
      }
      const Vector3d a = vertices[t[0]], b = vertices[t[1]], c = vertices[t[2]];
      const Vector3d p = a + u * (b - a) + v * (c - a);
      const Vector3d n = (b - a).cross(c - a).normalized();
      Vector3d direction;
      do {
        direction = Vector3d(normal(random), normal(random), normal(random)).normalized();
      } while (direction.dot(-n) < 0.5);
      const double length = (0.1 + 0.9 * unit(random)) * mm;
      const double before = unit(random) * length;
      segments_.push_back({p - before * direction, p + (length - before) * direction});
      near_points_.push_back(p + (2 * unit(random) - 1) * 2 * mm * n);
      box_points_.push_back(0.5 * (lower + upper) + 0.6 * (upper - lower).cwiseProduct(
                                                                Vector3d(unit(random), unit(random), unit(random)) -
                                                                Vector3d::Constant(0.5)) * 2);
    }
    const auto morton = [&](const Vector3d& p) {
      std::uint64_t code = 0;
      for (int bit = 9; bit >= 0; --bit) {
        for (int i = 0; i < 3; ++i) {
          const auto cell = static_cast<std::uint64_t>(std::clamp((p[i] - lower[i]) / (upper[i] - lower[i]), 0.0, 1.0) * 1023);
          code = (code << 1) | ((cell >> bit) & 1);
        }
      }
      return code;
    };
    coherent_segments_ = segments_;
    std::sort(coherent_segments_.begin(), coherent_segments_.end(),
              [&](const Segment& p, const Segment& q) { return morton(p.from) < morton(q.from); });
  }

  const TriangleSurface& surface() const { return surface_; }
  const std::vector<Segment>& segments() const { return segments_; }
  /// The same moves in Morton order of their starts: consecutive queries are close, as the
  /// tool's are in a haptic loop, so the nodes they need are mostly cached.
  const std::vector<Segment>& coherent_segments() const { return coherent_segments_; }
  const std::vector<Vector3d>& near_points() const { return near_points_; }
  const std::vector<Vector3d>& box_points() const { return box_points_; }

  const BoundingVolumeHierarchy& tree(const BvhSettings& settings) {
    auto& slot = trees_[key(settings)];
    if (!slot) slot = std::make_unique<BoundingVolumeHierarchy>(surface_, settings);
    return *slot;
  }
  const EmbreeScene& embree() {
    if (!embree_) embree_ = std::make_unique<EmbreeScene>(surface_.vertices(), surface_.triangles());
    return *embree_;
  }

 private:
  TriangleSurface surface_;
  std::vector<Segment> segments_;
  std::vector<Segment> coherent_segments_;
  std::vector<Vector3d> near_points_;
  std::vector<Vector3d> box_points_;
  using Key = std::tuple<BoundingVolume, int, int, double, bool>;
  static Key key(const BvhSettings& s) {
    return {s.bounding_volume, s.max_leaf_triangles, s.children_per_node, s.entry_grid_cell, s.float_leaf_test};
  }
  std::map<Key, std::unique_ptr<BoundingVolumeHierarchy>> trees_;
  std::unique_ptr<EmbreeScene> embree_;
};

Scene& sphere_scene(int frequency) {
  static std::map<int, std::unique_ptr<Scene>> scenes;
  auto& scene = scenes[frequency];
  if (!scene) scene = std::make_unique<Scene>(geodesic_sphere(frequency, radius_m));
  return *scene;
}

BvhSettings tree_settings(BoundingVolume volume, int width, int leaf, double grid) {
  BvhSettings settings;
  settings.bounding_volume = volume;
  settings.children_per_node = width;
  settings.max_leaf_triangles = leaf;
  settings.entry_grid_cell = grid;
  return settings;
}

std::string tree_name(const BvhSettings& s) {
  std::ostringstream name;
  name << (s.bounding_volume == BoundingVolume::obb ? "obb" : "aabb") << "/width:" << s.children_per_node
       << "/leaf:" << s.max_leaf_triangles << "/grid:" << s.entry_grid_cell;
  if (!s.float_leaf_test) name << "/double_leaves";
  return name.str();
}

/// Per-query averages of a counting pass, as benchmark counters. `descents`: the inner nodes
/// entered, (box_tests − 1) / 2 — meaningful for a binary tree without the entry grid, where
/// each query tests the root's box and then both children of every node it enters.
void set_counters(benchmark::State& state, const QueryCounters& counters, const BoundingVolumeHierarchy& tree,
                  bool descents) {
  const double queries = static_cast<double>(counters.queries);
  state.counters["box_tests"] = static_cast<double>(counters.box_tests) / queries;
  state.counters["triangle_tests"] = static_cast<double>(counters.triangle_tests) / queries;
  if (descents) state.counters["descents"] = static_cast<double>(counters.box_tests - counters.queries) / 2 / queries;
  state.counters["triangles"] = static_cast<double>(tree.stats().triangle_count);
  state.counters["depth"] = tree.stats().depth;
}

void first_contact(benchmark::State& state, Scene* scene, BvhSettings settings, bool coherent) {
  const BoundingVolumeHierarchy& tree = scene->tree(settings);
  const std::vector<Segment>& segments = coherent ? scene->coherent_segments() : scene->segments();
  QueryCounters counters;
  int hits = 0;
  for (const Segment& s : segments) hits += tree.first_hit_segment(s.from, s.to, &counters).hit;
  if (hits != query_count) state.SkipWithError("a first-contact segment missed the surface");
  std::size_t i = 0;
  for (auto _ : state) {
    const SurfaceHit hit = tree.first_hit_segment(segments[i].from, segments[i].to);
    benchmark::DoNotOptimize(hit);
    i = (i + 1) & (query_count - 1);
  }
  set_counters(state, counters, tree, settings.children_per_node == 2 && settings.entry_grid_cell == 0);
}

void first_contact_embree(benchmark::State& state, Scene* scene, bool coherent) {
  const EmbreeScene& embree = scene->embree();
  const std::vector<Segment>& segments = coherent ? scene->coherent_segments() : scene->segments();
  int hits = 0;
  for (const Segment& s : segments) hits += embree.first_hit(s.from, s.to - s.from, 1.0).second >= 0;
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(embree.first_hit(segments[i].from, segments[i].to - segments[i].from, 1.0));
    i = (i + 1) & (query_count - 1);
  }
  state.counters["hit_fraction"] = static_cast<double>(hits) / query_count;
  state.counters["triangles"] = static_cast<double>(scene->surface().triangles().size());
}

/// The ratio to Embree as a paired measurement: each iteration times all the moves through the
/// tree and through Embree back to back (in alternating order), so that a shared machine's
/// slow phases load both alike. Counters: the median over the iterations of the per-query
/// times and of their ratio; the reported time is the tree's.
void first_contact_against_embree(benchmark::State& state, Scene* scene, BvhSettings settings) {
  const BoundingVolumeHierarchy& tree = scene->tree(settings);
  const EmbreeScene& embree = scene->embree();
  const std::vector<Segment>& segments = scene->segments();
  QueryCounters counters;
  for (const Segment& s : segments) tree.first_hit_segment(s.from, s.to, &counters);
  using Clock = std::chrono::steady_clock;
  const auto time_tree = [&] {
    const auto start = Clock::now();
    for (const Segment& s : segments) benchmark::DoNotOptimize(tree.first_hit_segment(s.from, s.to));
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  const auto time_embree = [&] {
    const auto start = Clock::now();
    for (const Segment& s : segments) benchmark::DoNotOptimize(embree.first_hit(s.from, s.to - s.from, 1.0));
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  std::vector<double> ours, theirs, ratios;
  bool tree_first = true;
  for (auto _ : state) {
    double tree_s = 0, embree_s = 0;
    if (tree_first) {
      tree_s = time_tree();
      embree_s = time_embree();
    } else {
      embree_s = time_embree();
      tree_s = time_tree();
    }
    tree_first = !tree_first;
    state.SetIterationTime(tree_s / query_count);
    ours.push_back(tree_s / query_count * 1e9);
    theirs.push_back(embree_s / query_count * 1e9);
    ratios.push_back(tree_s / embree_s);
  }
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  if (!ratios.empty()) {
    state.counters["tree_ns"] = median(ours);
    state.counters["embree_ns"] = median(theirs);
    state.counters["ratio"] = median(ratios);
  }
  set_counters(state, counters, tree, false);
}

void closest_point(benchmark::State& state, Scene* scene, BvhSettings settings) {
  const BoundingVolumeHierarchy& tree = scene->tree(settings);
  const std::vector<Vector3d>& points = scene->near_points();
  QueryCounters counters;
  for (const Vector3d& x : points) benchmark::DoNotOptimize(tree.closest_point(x, &counters));
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(tree.closest_point(points[i]));
    i = (i + 1) & (query_count - 1);
  }
  set_counters(state, counters, tree, false);
}

/// The existing AABB tree of TriangleSurface (leaves of 4), for comparison.
void closest_point_triangle_surface(benchmark::State& state, Scene* scene) {
  const std::vector<Vector3d>& points = scene->near_points();
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(scene->surface().project(points[i]));
    i = (i + 1) & (query_count - 1);
  }
}

void contains(benchmark::State& state, Scene* scene, BvhSettings settings) {
  const BoundingVolumeHierarchy& tree = scene->tree(settings);
  const std::vector<Vector3d>& points = scene->box_points();
  QueryCounters counters;
  for (const Vector3d& x : points) benchmark::DoNotOptimize(tree.contains(x, &counters));
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(tree.contains(points[i]));
    i = (i + 1) & (query_count - 1);
  }
  set_counters(state, counters, tree, false);
}

void build(benchmark::State& state, Scene* scene, BvhSettings settings) {
  for (auto _ : state) {
    BoundingVolumeHierarchy tree(scene->surface(), settings);
    benchmark::DoNotOptimize(tree.stats());
  }
}

/// Refit after moving every vertex (a uniform 1 % swelling alternating with the original shape).
void refit(benchmark::State& state, Scene* scene, BvhSettings settings) {
  BoundingVolumeHierarchy tree(scene->surface(), settings);
  const std::vector<Vector3d>& original = scene->surface().vertices();
  std::vector<Vector3d> swollen = original;
  for (Vector3d& v : swollen) v *= 1.01;
  bool flip = false;
  for (auto _ : state) {
    tree.refit(flip ? original : swollen);
    flip = !flip;
    benchmark::ClobberMemory();
  }
}

void register_scene(const std::string& label, Scene* scene) {
  constexpr BoundingVolume volumes[] = {BoundingVolume::obb, BoundingVolume::aabb};
  const auto add = [&](const std::string& kind, auto function, const BvhSettings& settings) {
    return benchmark::RegisterBenchmark((kind + "/" + label + "/" + tree_name(settings)).c_str(), function, scene,
                                        settings);
  };
  const auto add_contact = [&](const std::string& kind, const BvhSettings& settings, bool coherent) {
    benchmark::RegisterBenchmark((kind + "/" + label + "/" + tree_name(settings)).c_str(), first_contact, scene,
                                 settings, coherent);
  };
  // Width × leaf size with the default grid; the paper's binary tree without grid; the grid's
  // cell size; Embree; then the default and the fastest trees on coherent moves.
  for (int width : {4, 2}) {
    for (int leaf : {1, 2, 4, 8}) {
      for (BoundingVolume volume : volumes) add_contact("first_contact", tree_settings(volume, width, leaf, 2), false);
    }
  }
  for (BoundingVolume volume : volumes) add_contact("first_contact", tree_settings(volume, 2, 1, 0), false);
  // The leaves' float pre-test against testing every triangle of a leaf in double.
  for (BoundingVolume volume : volumes) {
    BvhSettings double_leaves = tree_settings(volume, 4, 4, 2);
    double_leaves.float_leaf_test = false;
    add_contact("first_contact", double_leaves, false);
  }
  for (double grid : {0.0, 1.0, 4.0}) {
    for (BoundingVolume volume : volumes) add_contact("first_contact", tree_settings(volume, 4, 2, grid), false);
  }
  benchmark::RegisterBenchmark(("first_contact/" + label + "/embree").c_str(), first_contact_embree, scene, false);
  for (BoundingVolume volume : volumes) {
    for (int leaf : {1, 2}) add_contact("first_contact_coherent", tree_settings(volume, 4, leaf, 2), true);
  }
  for (BoundingVolume volume : volumes) {
    for (int leaf : {2, 4}) {
      add("first_contact_against_embree", first_contact_against_embree, tree_settings(volume, 4, leaf, 2))
          ->UseManualTime()
          ->Iterations(200);
    }
  }
  benchmark::RegisterBenchmark(("first_contact_coherent/" + label + "/embree").c_str(), first_contact_embree, scene,
                               true);

  for (BoundingVolume volume : volumes) {
    for (const BvhSettings& settings : {tree_settings(volume, 4, 1, 2), tree_settings(volume, 4, 2, 2),
                                        tree_settings(volume, 2, 1, 2)}) {
      add("closest_point", closest_point, settings);
    }
  }
  benchmark::RegisterBenchmark(("closest_point/" + label + "/triangle_surface").c_str(),
                               closest_point_triangle_surface, scene);
  for (BoundingVolume volume : volumes) add("contains", contains, tree_settings(volume, 4, 2, 2));
  for (BoundingVolume volume : volumes) {
    for (int width : {4, 2}) {
      add("build", build, tree_settings(volume, width, 1, 2))->Unit(benchmark::kMillisecond);
      add("refit", refit, tree_settings(volume, width, 1, 2))->Unit(benchmark::kMicrosecond);
    }
  }
}

/// The paper's sizes, then any organ meshes. Surfaces and their queries are made here, before
/// main (registration needs them); trees and Embree scenes when a benchmark first uses them.
const bool registered = [] {
  using Size = std::pair<int, const char*>;
  for (const auto& [frequency, label] : {Size{5, "500"}, Size{11, "2.5K"}, Size{29, "17K"}, Size{42, "35K"}}) {
    register_scene(label, &sphere_scene(frequency));
  }
  if (const char* directory = std::getenv("TOUCHSTONE_ORGAN_MESH_DIR")) {
    std::error_code error;
    for (const auto& entry : std::filesystem::directory_iterator(directory, error)) {
      if (entry.path().extension() != ".msh") continue;
      try {
        static std::vector<std::unique_ptr<Scene>> organs;
        organs.push_back(std::make_unique<Scene>(touchstone::meshes::load_msh_surface(entry.path().string())));
        register_scene(entry.path().stem().string(), organs.back().get());
      } catch (const std::exception& e) {
        std::cerr << "collision_benchmark: skipping " << entry.path() << ": " << e.what() << "\n";
      }
    }
    if (error) std::cerr << "collision_benchmark: cannot list " << directory << ": " << error.message() << "\n";
  }
  return true;
}();

}  // namespace
