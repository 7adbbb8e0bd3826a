// TriangleSurface queries on a ~20k-triangle sphere (icosphere level 5, R = 50 mm): project()
// and contains() through the AABB tree, for query points spread over the bounding box, points
// within 1 mm of the surface (node sprinkling's surface nodes) and points far outside; the
// brute-force closest point over all triangles is the baseline; construction (validation,
// normals, tree) is timed too.
//
//   ./build/release/benchmarks/surface_benchmark
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace {

using Eigen::Vector3d;
using Eigen::Vector3i;
using touchstone::geometry::TriangleSurface;
using touchstone::geometry::TriangleMeshData;
using touchstone::geometry::icosphere;

constexpr double radius_m = 0.05;
constexpr int query_count = 4096;

using Mesh = TriangleMeshData;

const Mesh& sphere_mesh() {
  static const Mesh mesh = icosphere(5, radius_m);
  return mesh;
}

const TriangleSurface& sphere() {
  static const TriangleSurface surface(sphere_mesh().vertices, sphere_mesh().triangles, "icosphere level 5");
  return surface;
}

enum class Queries { box, near_surface, far };

/// Fixed-seed query points: uniform in the box [-1.2 R, 1.2 R]³ (about half inside), within
/// ±1 mm of the sphere, or at 2–3 R from the centre.
std::vector<Vector3d> queries(Queries kind) {
  std::mt19937_64 random(42);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Vector3d> points;
  for (int i = 0; i < query_count; ++i) {
    const Vector3d direction = Vector3d(2 * unit(random) - 1, 2 * unit(random) - 1, 2 * unit(random) - 1);
    switch (kind) {
      case Queries::box:
        points.push_back(1.2 * radius_m * direction);
        break;
      case Queries::near_surface:
        points.push_back((radius_m + 1e-3 * (2 * unit(random) - 1)) * direction.normalized());
        break;
      case Queries::far:
        points.push_back(radius_m * (2 + unit(random)) * direction.normalized());
        break;
    }
  }
  return points;
}

void project(benchmark::State& state, Queries kind) {
  const TriangleSurface& surface = sphere();
  const std::vector<Vector3d> points = queries(kind);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(surface.project(points[i]));
    i = (i + 1) % points.size();
  }
  state.counters["triangles"] = static_cast<double>(surface.triangles().size());
}

void contains(benchmark::State& state, Queries kind) {
  const TriangleSurface& surface = sphere();
  const std::vector<Vector3d> points = queries(kind);
  std::size_t i = 0;
  std::size_t inside = 0;
  for (auto _ : state) {
    const bool result = surface.contains(points[i]);
    benchmark::DoNotOptimize(result);
    inside += result;
    i = (i + 1) % points.size();
  }
  state.counters["inside_fraction"] = static_cast<double>(inside) / static_cast<double>(state.iterations());
}

/// Closest distance over all triangles (Ericson's point–triangle test), the baseline.
double brute_force_distance(const TriangleSurface& surface, const Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const Vector3i& t : surface.triangles()) {
    const Vector3d& a = surface.vertices()[t[0]];
    const Vector3d& b = surface.vertices()[t[1]];
    const Vector3d& c = surface.vertices()[t[2]];
    const Vector3d ab = b - a;
    const Vector3d ac = c - a;
    const Vector3d bc = c - b;
    // Barycentric projection, clamped by falling back to the three edges when outside.
    const Vector3d n = ab.cross(ac);
    const Vector3d q = p - n * ((p - a).dot(n) / n.squaredNorm());
    double d;
    if (ab.cross(q - a).dot(n) >= 0 && bc.cross(q - b).dot(n) >= 0 && (a - c).cross(q - c).dot(n) >= 0) {
      d = (p - q).squaredNorm();
    } else {
      const auto segment = [&](const Vector3d& s, const Vector3d& e) {
        const double u = std::clamp((p - s).dot(e - s) / (e - s).squaredNorm(), 0.0, 1.0);
        return (s + u * (e - s) - p).squaredNorm();
      };
      d = std::min({segment(a, b), segment(b, c), segment(c, a)});
    }
    best = std::min(best, d);
  }
  return std::sqrt(best);
}

void project_brute_force(benchmark::State& state) {
  const TriangleSurface& surface = sphere();
  const std::vector<Vector3d> points = queries(Queries::box);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(brute_force_distance(surface, points[i]));
    i = (i + 1) % points.size();
  }
}

void construct(benchmark::State& state) {
  const Mesh& mesh = sphere_mesh();
  for (auto _ : state) {
    TriangleSurface surface(mesh.vertices, mesh.triangles);
    benchmark::DoNotOptimize(surface.area_m2());
  }
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
}

BENCHMARK_CAPTURE(project, box, Queries::box);
BENCHMARK_CAPTURE(project, near_surface, Queries::near_surface);
BENCHMARK_CAPTURE(project, far, Queries::far);
BENCHMARK_CAPTURE(contains, box, Queries::box);
BENCHMARK_CAPTURE(contains, near_surface, Queries::near_surface);
BENCHMARK(project_brute_force)->Unit(benchmark::kMicrosecond);
BENCHMARK(construct)->Unit(benchmark::kMillisecond);

}  // namespace
