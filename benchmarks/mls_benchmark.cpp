// One MLS evaluation with values, gradients and Hessians (what a collocation row needs), for the
// quadratic basis with ~30 and ~60 neighbours and the linear basis with ~15; and with ~30
// neighbours the values and gradients of a Galerkin volume point and the values of a boundary
// point. Candidates are the nodes within 1.3 r of the point, as a coarse neighbour search would
// give. Then a batch of points with every node a candidate (the enriched model's rules), side by
// side in the lanes of evaluate_mls_batch against one evaluate_mls each, for both bases.

#include "touchstone/realtime/mfs/mls_shape_functions.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace {

using touchstone::realtime::mfs::Basis;
using touchstone::realtime::mfs::Derivatives;
using touchstone::realtime::mfs::evaluate_mls;
using touchstone::realtime::mfs::evaluate_mls_batch;
using touchstone::realtime::mfs::MlsEvaluation;
using touchstone::realtime::mfs::MlsSettings;
using touchstone::realtime::mfs::MlsStatus;

constexpr double h = 1e-3;  // node spacing [m]

struct Scene {
  std::vector<Eigen::Vector3d> positions;
  std::vector<double> radii;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::vector<int>> candidates;
};

/// Jittered 10³ lattice with radius c·h, c from the wanted mean neighbour count (4/3 π c³ ≈ n),
/// and 64 random evaluation points in its interior.
Scene make_scene(double neighbours) {
  Scene scene;
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  constexpr double pi = 3.14159265358979323846;
  const double radius = std::cbrt(3.0 * neighbours / (4.0 * pi)) * h;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      for (int k = 0; k < 10; ++k) {
        scene.positions.push_back(h * Eigen::Vector3d(i + jitter(rng), j + jitter(rng), k + jitter(rng)));
        scene.radii.push_back(radius);
      }
  std::uniform_real_distribution<double> inside(3.5 * h, 5.5 * h);
  for (int p = 0; p < 64; ++p) {
    const Eigen::Vector3d x(inside(rng), inside(rng), inside(rng));
    scene.points.push_back(x);
    std::vector<int> near;
    for (int j = 0; j < static_cast<int>(scene.positions.size()); ++j)
      if ((scene.positions[j] - x).norm() < 1.3 * radius) near.push_back(j);
    scene.candidates.push_back(near);
  }
  return scene;
}

void evaluate(benchmark::State& state, Basis basis, double neighbours, Derivatives derivatives = Derivatives::hessians) {
  const Scene scene = make_scene(neighbours);
  const MlsSettings settings{basis};
  MlsEvaluation result;
  std::size_t point = 0;
  double found = 0.0;
  std::int64_t evaluations = 0;
  for (auto _ : state) {
    evaluate_mls(scene.points[point], scene.positions, scene.radii, scene.candidates[point], settings,
                 derivatives, result);
    benchmark::DoNotOptimize(result.value.data());
    benchmark::DoNotOptimize(result.gradient.data());
    benchmark::DoNotOptimize(result.hessian.data());
    if (result.status != MlsStatus::ok) {
      state.SkipWithError("MLS evaluation failed");
      break;
    }
    found += static_cast<double>(result.neighbours.size());
    ++evaluations;
    point = (point + 1) % scene.points.size();
  }
  state.counters["neighbours"] = evaluations > 0 ? found / static_cast<double>(evaluations) : 0.0;
}

void BM_mls_quadratic_30(benchmark::State& state) { evaluate(state, Basis::quadratic, 30.0); }
void BM_mls_quadratic_60(benchmark::State& state) { evaluate(state, Basis::quadratic, 60.0); }
void BM_mls_linear_15(benchmark::State& state) { evaluate(state, Basis::linear, 15.0); }
/// What a Galerkin volume point asks for (values and gradients) and a boundary point (values).
void BM_mls_quadratic_30_gradients(benchmark::State& state) { evaluate(state, Basis::quadratic, 30.0, Derivatives::gradients); }
void BM_mls_quadratic_30_values(benchmark::State& state) { evaluate(state, Basis::quadratic, 30.0, Derivatives::values); }

/// Values and gradients at a batch of mls_batch_size points (eight with AVX-512, else four),
/// every node a candidate: state.range(0) = 1 runs the batch side by side (evaluate_mls_batch),
/// 0 one by one; the time is per point.
void batch_of_points(benchmark::State& state, Basis basis, double neighbours) {
  constexpr int batch = touchstone::realtime::mfs::mls_batch_size;
  const Scene scene = make_scene(neighbours);
  const MlsSettings settings{basis};
  const bool side_by_side = state.range(0) == 1;
  MlsEvaluation results[batch];
  std::size_t first = 0;
  for (auto _ : state) {
    const Eigen::Vector3d* x = scene.points.data() + first;
    if (side_by_side) {
      evaluate_mls_batch(x, batch, scene.positions, scene.radii, settings, Derivatives::gradients, results);
    } else {
      for (int k = 0; k < batch; ++k) evaluate_mls(x[k], scene.positions, scene.radii, {}, settings, Derivatives::gradients, results[k]);
    }
    for (const MlsEvaluation& r : results) {
      benchmark::DoNotOptimize(r.gradient.data());
      if (r.status != MlsStatus::ok) state.SkipWithError("MLS evaluation failed");
    }
    first = (first + batch) % scene.points.size();
  }
  state.SetItemsProcessed(batch * state.iterations());
  state.counters["points_per_batch"] = batch;
  state.counters["time_per_point"] = benchmark::Counter(batch * static_cast<double>(state.iterations()),
                                                        benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_mls_batch_quadratic_30(benchmark::State& state) { batch_of_points(state, Basis::quadratic, 30.0); }
void BM_mls_batch_linear_30(benchmark::State& state) { batch_of_points(state, Basis::linear, 30.0); }

BENCHMARK(BM_mls_quadratic_30);
BENCHMARK(BM_mls_quadratic_60);
BENCHMARK(BM_mls_linear_15);
BENCHMARK(BM_mls_quadratic_30_gradients);
BENCHMARK(BM_mls_quadratic_30_values);
BENCHMARK(BM_mls_batch_quadratic_30)->ArgName("side_by_side")->Arg(0)->Arg(1);
BENCHMARK(BM_mls_batch_linear_30)->ArgName("side_by_side")->Arg(0)->Arg(1);

}  // namespace
