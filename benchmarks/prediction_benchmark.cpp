// Collision prediction (paper §3.1–3.2; target: ≤ 20 ns per haptic cycle once a collision is
// predicted) and the tremor model:
// - cheap_cycle: CollisionPredictor::step() while the tip wobbles inside its certified ball —
//   one squared distance, one comparison, the history sample every 10th cycle, no query;
// - prediction: one predict_collision() (closest point at the anchor is given; a ray cast and
//   the corridor's closest-point queries) 5 mm from an icosphere at 45°, through the
//   BRUTE-FORCE test queries (every triangle, box-rejected): a stand-in until the BVH lands,
//   so its time scales with the triangle count and says nothing about the BVH;
// - approach_per_cycle: a whole approach with tremor (rest, approach, press, release), mean
//   time per cycle, brute-force queries as above;
// - mean_tool_path: eq. 2 over m = 30 (evaluated when the tip leaves its corridor);
// - tremor_sample: one 3-D tremor sample (6 biquads per axis, or 32 sinusoids per axis).
//
//   ./build/release/benchmarks/prediction_benchmark --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include "brute_force_queries.hpp"

#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/realtime/hand_motion/tremor_model.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <vector>

namespace {

using Eigen::Vector3d;
using touchstone::realtime::hand_motion::ApproachSettings;
using touchstone::realtime::hand_motion::ApproachTrajectoryGenerator;
using touchstone::realtime::collision::CollisionPrediction;
using touchstone::realtime::collision::CollisionPredictor;
using touchstone::realtime::collision::Corridor;
using touchstone::realtime::collision::PredictionSettings;
using touchstone::realtime::collision::PredictionStatus;
using touchstone::realtime::collision::QueryCounters;
using touchstone::realtime::hand_motion::RandomStream;
using touchstone::realtime::collision::ToolPathHistory;
using touchstone::realtime::hand_motion::TremorGenerator;
using touchstone::realtime::hand_motion::TremorSettings;
using touchstone::realtime::hand_motion::TremorSpectrum;
using touchstone::realtime::collision::predict_collision;
using touchstone::realtime::collision::testing::BruteForceQueries;
namespace geometry = touchstone::geometry;

constexpr double radius_m = 0.05;

struct Sphere {
  explicit Sphere(int level)
      : mesh(geometry::icosphere(level, radius_m)),
        surface(mesh.vertices, mesh.triangles, "icosphere"),
        queries(surface) {}
  geometry::TriangleMeshData mesh;
  geometry::TriangleSurface surface;
  BruteForceQueries queries;
};

const Sphere& sphere(int level) {
  static std::map<int, std::unique_ptr<Sphere>> spheres;
  auto& slot = spheres[level];
  if (!slot) slot = std::make_unique<Sphere>(level);
  return *slot;
}

void cheap_cycle(benchmark::State& state) {
  // 10 mm off the surface, in a certified ball of about 2.4 mm (out of the straight-line range:
  // D − 7.5 mm); the tip wanders ±0.2 mm around the anchor. Every cycle must stay `free`.
  const Sphere& s = sphere(3);
  CollisionPredictor predictor(s.queries, PredictionSettings{});
  const Vector3d anchor(0, 0, radius_m + 0.010);
  predictor.step(anchor);
  const long long setup_queries = predictor.counters().queries.queries;
  RandomStream random(1);
  std::array<Vector3d, 1024> positions;
  for (Vector3d& p : positions)
    p = anchor + 2e-4 * Vector3d(random.uniform() - 0.5, random.uniform() - 0.5, random.uniform() - 0.5);
  std::size_t i = 0;
  long long not_free = 0;
  for (auto _ : state) {
    const auto out = predictor.step(positions[i++ & 1023]);
    not_free += out.status != PredictionStatus::free;
    benchmark::DoNotOptimize(out.status);
  }
  if (not_free > 0) state.SkipWithError("a cycle left the certified ball");
  state.counters["surface_queries"] = static_cast<double>(predictor.counters().queries.queries - setup_queries);
}
BENCHMARK(cheap_cycle);

void prediction(benchmark::State& state) {
  const Sphere& s = sphere(static_cast<int>(state.range(0)));
  const PredictionSettings settings;
  // 5 mm out along a direction 45° off the normal at a surface point, moving back along it.
  const Vector3d normal = Vector3d(0.2, 0.3, 1).normalized();
  const Vector3d point = s.queries.first_hit_ray(2 * radius_m * normal, -normal, 2 * radius_m).point;
  const Vector3d outward = (normal + normal.unitOrthogonal()).normalized();
  const Vector3d anchor = point + 0.005 * outward;
  const auto closest = s.queries.closest_point(anchor);
  Corridor corridor;
  long long closest_queries = 0, rays = 0;
  QueryCounters counters;
  for (auto _ : state) {
    const CollisionPrediction p = predict_collision(s.queries, settings, anchor, closest, -0.003 * outward, 0.15,
                                                    0.0, corridor, &counters, &closest_queries, &rays);
    benchmark::DoNotOptimize(p.point);
  }
  const double n = static_cast<double>(state.iterations());
  state.SetLabel("brute-force queries, " + std::to_string(s.mesh.triangles.size()) + " triangles");
  state.counters["closest_point_queries"] = closest_queries / n;
  state.counters["ray_casts"] = rays / n;
  state.counters["corridor_balls"] = corridor.size;
  state.counters["triangle_tests"] = counters.triangle_tests / n;
}
BENCHMARK(prediction)->Arg(3)->Arg(5)->Unit(benchmark::kMicrosecond);

void approach_per_cycle(benchmark::State& state) {
  const Sphere& s = sphere(3);
  ApproachSettings approach;
  approach.tremor.rms_per_axis_m = 2e-4;
  const ApproachTrajectoryGenerator generator(s.surface, approach);
  std::vector<std::vector<Vector3d>> paths;
  for (int seed = 1; seed <= 16; ++seed) paths.push_back(generator.generate(seed).tip);
  std::size_t which = 0;
  long long cycles = 0;
  for (auto _ : state) {
    CollisionPredictor predictor(s.queries, PredictionSettings{});
    for (const Vector3d& p : paths[which++ % paths.size()]) benchmark::DoNotOptimize(predictor.step(p).status);
    cycles += static_cast<long long>(paths[(which - 1) % paths.size()].size());
  }
  state.SetItemsProcessed(cycles);
  state.SetLabel("brute-force queries, 1280 triangles; items = cycles");
}
BENCHMARK(approach_per_cycle)->Unit(benchmark::kMillisecond);

void mean_tool_path(benchmark::State& state) {
  ToolPathHistory history(30);
  for (int k = 0; k < 30; ++k) history.push(Vector3d(1e-4 * k, 0, 0));
  Vector3d current(3e-3, 1e-4, 0);
  for (auto _ : state) {
    benchmark::DoNotOptimize(current);
    benchmark::DoNotOptimize(history.mean_tool_path(current));
  }
}
BENCHMARK(mean_tool_path);

void tremor_sample(benchmark::State& state) {
  TremorSettings settings;
  settings.spectrum = state.range(0) == 0 ? TremorSpectrum::band_noise : TremorSpectrum::sinusoids;
  TremorGenerator generator(settings);
  for (auto _ : state) benchmark::DoNotOptimize(generator.next());
  state.SetLabel(state.range(0) == 0 ? "band_noise, 6 biquads per axis" : "sinusoids, 32 per axis");
}
BENCHMARK(tremor_sample)->Arg(0)->Arg(1);

}  // namespace
