// The real-time MFS local model (targets: 34 nodes ≤ 20 µs, 200 nodes ≤ 1 ms) on a closed sphere
// of radius R = 50 mm (icosphere level 5, 20 480 triangles), the tool (a = 2.5 mm) at the top pole
// pushing along −z, E = 10 kPa, ν = 0.45, local radius L = 12.5 mm:
//   BM_Build/<N>/<solver>/oversampling:<v>  the whole model update (sprinkle, shape functions,
//                                           assembly, factorisation, condensation to K_t)
//   BM_PaperMode34                          the paper's 34-node model (its 3.6 ms row; target 20 µs)
//   BM_AssembleAndSolve/<N>/<solver>        assembly, factorisation and the three tool solves on a
//                                           cloud sprinkled once: the build without sprinkler or force maps
//   BM_HapticTick                           F = K_t U_tool, once per haptic tick
//   BM_SolveLocalModel/<N>                  the full response to one U_tool from the unit responses
// The reaction and energy force extractions are study diagnostics (volume and surface quadrature,
// far slower than a model update), not part of the model loop, so they are off everywhere here.
// Split times are counters in ms per iteration; Google Benchmark prints 0.25 as "250m", i.e.
// 0.25 ms.
//
//   ./build/release/benchmarks/mfs_benchmark --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/collocation.hpp"
#include "touchstone/realtime/mfs/enriched_galerkin.hpp"
#include "touchstone/realtime/mfs/linear_solvers.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"
#include "touchstone/realtime/mfs/local_surface.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <benchmark/benchmark.h>

#include <chrono>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

namespace {

using touchstone::geometry::icosphere;
using touchstone::geometry::TriangleMeshData;
using touchstone::geometry::TriangleSurface;
using touchstone::realtime::mfs::assemble_collocation;
using touchstone::realtime::mfs::build_local_model;
using touchstone::realtime::mfs::CollocationSolver;
using touchstone::realtime::mfs::CollocationSystem;
using touchstone::realtime::mfs::LocalModel;
using touchstone::realtime::mfs::LocalModelSettings;
using touchstone::realtime::mfs::LocalSolution;
using touchstone::geometry::Material;
using touchstone::realtime::mfs::NodeCloud;
using touchstone::realtime::mfs::paper_settings;
using touchstone::realtime::mfs::solve_local_model;
using touchstone::realtime::mfs::SolveReport;
using touchstone::realtime::mfs::SolverKind;
using touchstone::realtime::mfs::sprinkle_nodes;
using touchstone::realtime::mfs::SprinklingSettings;
using touchstone::realtime::mfs::ToolContact;

// The builds run under the allocator setting of the program that runs the model loop
// (touchstone): freed memory kept for reuse, so a build does not fault in the pages of the last,
// and the heap on transparent huge pages.
[[maybe_unused]] const bool memory_kept_for_reuse = touchstone::realtime::runtime::keep_freed_memory_for_reuse();
[[maybe_unused]] const std::size_t heap_bytes_advised = touchstone::realtime::runtime::advise_huge_pages_for_heap();

constexpr double organ_radius_m = 0.05;
constexpr int icosphere_level = 5;  // 20 · 4⁵ = 20 480 triangles
constexpr double tool_radius_m = 0.0025;
constexpr double local_radius_m = 0.0125;
constexpr double indentation_m = 0.25e-3;  // δ of B2: the range U_tool sweeps in the tick benchmarks

const SolverKind solver_kinds[] = {SolverKind::dense_lu, SolverKind::sparse_lu, SolverKind::gmres_ilut};
const int build_node_counts[] = {34, 100, 200, 400};
// 40 build-sized benchmarks at 10–2000 ms each: 0.2 s of CPU apiece keeps three repetitions of
// the whole program within about three minutes on a shared 2-core machine.
constexpr double build_min_time_s = 0.2;

const TriangleSurface& organ() {
  static const TriangleSurface surface = [] {
    const TriangleMeshData mesh = icosphere(icosphere_level, organ_radius_m);
    return TriangleSurface(mesh.vertices, mesh.triangles, "icosphere level 5");
  }();
  return surface;
}

ToolContact pole_contact() {
  ToolContact contact;
  // The pole is an icosphere vertex from level 1 on; projecting keeps it exact on the facets anyway.
  contact.point = organ().project(Eigen::Vector3d(0.0, 0.0, organ_radius_m)).point;
  contact.direction = Eigen::Vector3d(0.0, 0.0, -1.0);
  contact.radius_m = tool_radius_m;
  return contact;
}

Material tissue() {
  Material material;
  material.youngs_modulus_Pa = 10.0e3;
  material.poisson_ratio = 0.45;
  return material;
}

/// Collocation (the paper's formulation, built for the model loop) with N, the solver and
/// (when > 0) the oversampling; no study diagnostics.
LocalModelSettings loop_settings(int node_count, SolverKind kind, double oversampling = 0.0) {
  LocalModelSettings settings;
  settings.formulation = touchstone::realtime::mfs::Formulation::collocation;
  settings.force.haptic_method = touchstone::realtime::mfs::default_haptic_method(settings.formulation, false);
  settings.sprinkling.node_count = node_count;
  settings.sprinkling.local_radius_m = local_radius_m;
  if (oversampling > 0) settings.sprinkling.oversampling = oversampling;
  settings.solver.kind = kind;
  settings.force.reaction = false;
  settings.force.energy = false;
  settings.force.traction = false;  // a diagnostic unless it is the haptic method
  return settings;
}

/// One build outside the timed loop (the tick benchmarks only read the model); "" when it worked.
std::string build_once(const LocalModelSettings& settings, LocalModel& model) {
  try {
    model = build_local_model(organ(), pole_contact(), tissue(), settings);
  } catch (const std::exception& error) {
    return error.what();
  }
  return model.ok() ? std::string() : model.status;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

benchmark::Counter per_iteration(double value) { return benchmark::Counter(value, benchmark::Counter::kAvgIterations); }

/// build_local_model every iteration, the way the model loop rebuilds when the contact moves.
void build_with_contact(benchmark::State& state, const LocalModelSettings& settings, touchstone::geometry::ContactCondition condition) {
  const TriangleSurface& surface = organ();
  ToolContact contact = pole_contact();
  contact.condition = condition;
  const Material material = tissue();
  double sprinkle_s = 0, assembly_s = 0, factorize_s = 0, condense_s = 0, volume_s = 0, boundary_s = 0;
  double nodes = 0, extra_points = 0, stiffness_zz = 0, mls_evaluations = 0, point_nodes = 0, gram_overhead = 0;
  for (auto _ : state) {
    LocalModel model;
    try {
      model = build_local_model(surface, contact, material, settings);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      break;
    }
    if (!model.ok()) {
      state.SkipWithError(model.status.c_str());
      break;
    }
    benchmark::DoNotOptimize(model.tool_stiffness_N_per_m.data());
    sprinkle_s += model.times.sprinkle_s;
    assembly_s += model.times.assembly_s;
    factorize_s += model.times.factorize_s;
    condense_s += model.times.condense_s;
    nodes = static_cast<double>(model.cloud.size());
    extra_points = static_cast<double>(model.cloud.extra_points.size());
    stiffness_zz = model.tool_stiffness_N_per_m(2, 2);
    mls_evaluations = model.enriched.mls_evaluations;
    point_nodes = model.enriched.mean_volume_point_nodes;
    gram_overhead = model.enriched.gram_product_overhead;
    volume_s += model.enriched.volume_s;
    boundary_s += model.enriched.boundary_s;
  }
  state.counters["N"] = nodes;
  state.counters["extra"] = extra_points;
  state.counters["oversampling"] = settings.sprinkling.oversampling;
  // A sanity check that rides along: the B2 reference (F_z = −16.3 mN at U_z = −0.25 mm) gives +65 N/m.
  state.counters["K_zz_N_per_m"] = stiffness_zz;
  state.counters["sprinkle_ms"] = per_iteration(1e3 * sprinkle_s);
  state.counters["assembly_ms"] = per_iteration(1e3 * assembly_s);
  state.counters["factorize_ms"] = per_iteration(1e3 * factorize_s);
  state.counters["condense_ms"] = per_iteration(1e3 * condense_s);
  if (mls_evaluations > 0) {
    state.counters["mls_evaluations"] = mls_evaluations;
    // The enriched assembly's two parts: the volume rule, the boundary rules and constraint rows.
    state.counters["volume_ms"] = per_iteration(1e3 * volume_s);
    state.counters["boundary_ms"] = per_iteration(1e3 * boundary_s);
  }
  // Nodes per volume point: near N the MLS part is dense (its cost grows as N² per point).
  if (point_nodes > 0) state.counters["nodes_per_volume_point"] = point_nodes;
  // The Gram batches' products over what the points' own node sets need (1: none wasted).
  if (gram_overhead > 0) state.counters["gram_product_overhead"] = gram_overhead;
}

void build(benchmark::State& state, const LocalModelSettings& settings) {
  build_with_contact(state, settings, touchstone::geometry::ContactCondition::frictionless);
}

/// Assembly, factorisation and the three tool right-hand sides on a cloud sprinkled once: the
/// build minus the sprinkler and the force maps. A fresh solver each time, as build_local_model
/// makes one (no reuse of the sparse symbolic analysis).
void assemble_and_solve(benchmark::State& state, const LocalModelSettings& settings) {
  NodeCloud cloud;
  try {
    cloud = sprinkle_nodes(organ(), pole_contact(), settings.sprinkling);
  } catch (const std::exception& error) {
    state.SkipWithError(error.what());
    return;
  }
  const Material material = tissue();
  double assembly_s = 0, factorize_s = 0, solve_s = 0;
  for (auto _ : state) {
    auto step = std::chrono::steady_clock::now();
    CollocationSystem system;
    assemble_collocation(cloud, material, settings.collocation, system);
    assembly_s += seconds_since(step);
    if (!system.status.ok()) {
      state.SkipWithError(("shape functions failed at collocation point " + std::to_string(system.status.node)).c_str());
      break;
    }
    step = std::chrono::steady_clock::now();
    CollocationSolver solver(settings.solver);
    const SolveReport factorised = solver.factorize(system.stiffness);
    factorize_s += seconds_since(step);
    if (!factorised.ok) {
      state.SkipWithError(("factorisation: " + factorised.failure).c_str());
      break;
    }
    step = std::chrono::steady_clock::now();
    Eigen::MatrixXd response;
    const SolveReport solved = solver.solve(system.tool_rhs, response);
    solve_s += seconds_since(step);
    if (!solved.ok) {
      state.SkipWithError(("solve: " + solved.failure).c_str());
      break;
    }
    benchmark::DoNotOptimize(response.data());
  }
  state.counters["N"] = static_cast<double>(cloud.size());
  state.counters["extra"] = static_cast<double>(cloud.extra_points.size());
  state.counters["assembly_ms"] = per_iteration(1e3 * assembly_s);
  state.counters["factorize_ms"] = per_iteration(1e3 * factorize_s);
  state.counters["solve_ms"] = per_iteration(1e3 * solve_s);
}

void BM_PaperMode34(benchmark::State& state) {
  LocalModelSettings settings = paper_settings();
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.force.reaction = false;
  settings.force.energy = false;
  settings.force.traction = false;  // a diagnostic unless it is the haptic method
  build(state, settings);
}

/// The haptic loop's force: nine multiply-adds on a K_t that stays fixed until the next model
/// update, with U_tool creeping down to δ and back to zero (a predictable branch).
void BM_HapticTick(benchmark::State& state) {
  LocalModel model;
  const std::string failure = build_once(loop_settings(100, SolverKind::sparse_lu), model);
  if (!failure.empty()) {
    state.SkipWithError(failure.c_str());
    return;
  }
  const Eigen::Matrix3d stiffness = model.tool_stiffness_N_per_m;
  const Eigen::Vector3d step(1e-10, -0.5e-10, -1e-8);  // [m] per tick
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
  for (auto _ : state) {
    displacement += step;
    if (displacement.z() < -indentation_m) displacement.setZero();
    Eigen::Vector3d force = stiffness * displacement;
    benchmark::DoNotOptimize(force);
    benchmark::ClobberMemory();
  }
  state.counters["K_zz_N_per_m"] = stiffness(2, 2);
}

/// The response to one U_tool without a new solve: 3N parameters and the force maps.
void BM_SolveLocalModel(benchmark::State& state) {
  LocalModel model;
  const std::string failure = build_once(loop_settings(static_cast<int>(state.range(0)), SolverKind::sparse_lu), model);
  if (!failure.empty()) {
    state.SkipWithError(failure.c_str());
    return;
  }
  Eigen::Vector3d displacement(0.0, 0.0, -0.5 * indentation_m);
  for (auto _ : state) {
    displacement.z() = displacement.z() < -indentation_m ? -0.5 * indentation_m : displacement.z() - 1e-8;
    const LocalSolution solution = solve_local_model(model, displacement);
    benchmark::DoNotOptimize(solution.forces.haptic_N.data());
  }
  state.counters["N"] = static_cast<double>(model.cloud.size());
  state.counters["K_zz_N_per_m"] = model.tool_stiffness_N_per_m(2, 2);
}

/// The first Galerkin model (haptic force = the reaction), as the real-time model loop builds
/// it: no energy, no traction-integral diagnostic.
void BM_BuildGalerkin(benchmark::State& state) {
  LocalModelSettings settings;
  settings.formulation = touchstone::realtime::mfs::Formulation::galerkin;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.force.energy = false;
  settings.force.traction = false;
  build(state, settings);
}

/// The default, enriched model as the model loop builds it (sprinkle + quadratures + assembly +
/// the KKT solve + the condensation to K_t), with the clamped exterior (no atlas lookup): its
/// MLS evaluations per build are counted. At the benchmark's ν = 0.45 the default corrects the
/// MLS gradients on the 6 × 6 × 12 volume rule (EnrichedSettings::gradient_correction).
void BM_BuildEnriched(benchmark::State& state) {
  LocalModelSettings settings;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.enriched.exterior = touchstone::realtime::mfs::ExteriorCondition::clamped;
  build(state, settings);
}

// The enriched build's first phase (its `sprinkle_ms` counter), part by part: the surface fitted
// around the contact (with the build's reach), the even node cloud on it, and the quadratures.
constexpr double local_surface_reach_m =
    touchstone::realtime::mfs::enriched_surface_reach_local_radii * local_radius_m;

void BM_EnrichedLocalSurface(benchmark::State& state) {
  const ToolContact contact = pole_contact();
  for (auto _ : state) {
    const touchstone::realtime::mfs::LocalSurface surface(organ(), contact.point, local_surface_reach_m);
    benchmark::DoNotOptimize(surface.fitted());
  }
}

void BM_EnrichedSprinkle(benchmark::State& state) {
  const ToolContact contact = pole_contact();
  const touchstone::realtime::mfs::LocalSurface surface(organ(), contact.point, local_surface_reach_m);
  double nodes = 0;
  for (auto _ : state) {
    const auto cloud =
        touchstone::realtime::mfs::sprinkle_even_nodes(surface, contact, static_cast<int>(state.range(0)), local_radius_m);
    nodes = static_cast<double>(cloud.size());
    benchmark::DoNotOptimize(cloud.positions.data());
  }
  state.counters["N"] = nodes;
}

/// The default's settings at the benchmark's node count (state.range(0)), the rules chosen.
touchstone::realtime::mfs::EnrichedSettings enriched_settings_for(const benchmark::State& state) {
  namespace mfs = touchstone::realtime::mfs;
  return mfs::quadratures_for_node_count(mfs::settings_for_material(mfs::EnrichedSettings{}, tissue()),
                                         static_cast<std::size_t>(state.range(0)));
}

/// The enriched rules at a contact; false (the benchmark marked skipped) if they fail.
bool contact_quadratures(benchmark::State& state, const ToolContact& contact,
                         const touchstone::realtime::mfs::LocalSurface& surface,
                         const touchstone::realtime::mfs::EnrichedSettings& settings,
                         touchstone::realtime::mfs::EnrichedQuadratures& quadratures) {
  namespace mfs = touchstone::realtime::mfs;
  mfs::PunchFrame frame;
  std::string failure;
  if (mfs::enriched_quadratures(surface, contact, local_radius_m, settings, mfs::PatchQuadrature{}, quadratures, frame,
                                failure))
    return true;
  state.SkipWithError(failure.c_str());
  return false;
}

void BM_EnrichedQuadratures(benchmark::State& state) {
  namespace mfs = touchstone::realtime::mfs;
  const ToolContact contact = pole_contact();
  const mfs::LocalSurface surface(organ(), contact.point, local_surface_reach_m);
  const mfs::EnrichedSettings settings = enriched_settings_for(state);
  mfs::EnrichedQuadratures quadratures;
  for (auto _ : state) {
    if (!contact_quadratures(state, contact, surface, settings, quadratures)) break;
    benchmark::DoNotOptimize(quadratures.volume.points.data());
  }
  state.counters["volume_points"] = static_cast<double>(quadratures.volume.points.size());
  state.counters["boundary_points"] = static_cast<double>(
      quadratures.patch.points.size() + quadratures.free_surface.points.size() + quadratures.cut.points.size());
}

/// The build's support radii alone (enriched_support_radii) over every rule's points: the
/// nearest-node selections of the points that see too few nodes are most of it on small clouds.
void BM_EnrichedSupportRadii(benchmark::State& state) {
  namespace mfs = touchstone::realtime::mfs;
  const ToolContact contact = pole_contact();
  const mfs::LocalSurface surface(organ(), contact.point, local_surface_reach_m);
  const mfs::EnrichedSettings settings = enriched_settings_for(state);
  mfs::EnrichedQuadratures quadratures;
  if (!contact_quadratures(state, contact, surface, settings, quadratures)) return;
  const auto cloud = mfs::sprinkle_even_nodes(surface, contact, static_cast<int>(state.range(0)), local_radius_m);
  const std::vector<const mfs::PatchQuadrature*> sets = {&quadratures.volume, &quadratures.patch, &quadratures.free_surface,
                                                         &quadratures.cut, &quadratures.clamped};
  for (auto _ : state) {
    const std::vector<double> radii =
        mfs::enriched_support_radii(cloud.positions, sets, settings.support_neighbours, settings.min_point_neighbours);
    benchmark::DoNotOptimize(radii.data());
  }
  state.counters["N"] = static_cast<double>(cloud.size());
}

/// The same build with every shell of the volume rule at the full angular counts (the rule
/// before the inner shells were coarsened): the saving, measured in the same run.
void BM_BuildEnrichedUniformShells(benchmark::State& state) {
  LocalModelSettings settings;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.enriched.exterior = touchstone::realtime::mfs::ExteriorCondition::clamped;
  settings.enriched.volume_coarse_within_tool_radii = 0;
  build(state, settings);
}

/// The default's build from ν = 0.475 on, forced at the benchmark's ν: the MLS part's
/// volumetric term projected, on the 8 × 8 × 16 rule without a gradient correction. Against
/// BM_BuildEnrichedUncorrectedFineRule it differs only in the projection (the ψ divergence at
/// every volume point and the N × N products).
void BM_BuildEnrichedProjected(benchmark::State& state) {
  LocalModelSettings settings;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.enriched.exterior = touchstone::realtime::mfs::ExteriorCondition::clamped;
  settings.enriched.volumetric = touchstone::realtime::mfs::VolumetricTerm::projected;
  settings.enriched.gradient_correction = touchstone::realtime::mfs::GradientCorrection::none;
  build(state, settings);
}

/// The same with a bonded tool: three more singular fields (two tangential, one radial shear),
/// whose stresses are finite differences, and three times the patch multipliers.
void BM_BuildEnrichedBonded(benchmark::State& state) {
  LocalModelSettings settings;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.enriched.exterior = touchstone::realtime::mfs::ExteriorCondition::clamped;
  build_with_contact(state, settings, touchstone::geometry::ContactCondition::bonded);
}

/// The enriched model on the benchmark's contact with the clamped exterior and the MLS
/// gradients as they are (no correction to the volume rule).
LocalModelSettings enriched_uncorrected(const benchmark::State& state) {
  LocalModelSettings settings;
  settings.sprinkling.node_count = static_cast<int>(state.range(0));
  settings.sprinkling.local_radius_m = local_radius_m;
  settings.enriched.exterior = touchstone::realtime::mfs::ExteriorCondition::clamped;
  settings.enriched.gradient_correction = touchstone::realtime::mfs::GradientCorrection::none;
  return settings;
}

/// The uncorrected gradients on the finer 8 × 8 × 16 rule and the 8 × 16 cut rule (grown with N
/// as the default's): the default where the volumetric term is projected, and the model the
/// correction replaces below.
void BM_BuildEnrichedUncorrectedFineRule(benchmark::State& state) { build(state, enriched_uncorrected(state)); }

/// The default's 6 × 6 × 12 volume and 6 × 12 cut rules without the correction: what the
/// correction itself costs.
void BM_BuildEnrichedCoarseRule(benchmark::State& state) {
  LocalModelSettings settings = enriched_uncorrected(state);
  settings.enriched.volume_radial_points = 6;
  settings.enriched.volume_polar_points = 6;
  settings.enriched.volume_azimuth_points = 12;
  settings.enriched.cut_polar_points = 6;
  settings.enriched.cut_azimuth_points = 12;
  build(state, settings);
}

BENCHMARK(BM_PaperMode34)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BuildGalerkin)->Arg(34)->Arg(100)->Arg(200)->Iterations(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildEnriched)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EnrichedLocalSurface)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_EnrichedSprinkle)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_EnrichedQuadratures)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_EnrichedSupportRadii)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BuildEnrichedUniformShells)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildEnrichedProjected)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildEnrichedBonded)->Arg(34)->Arg(60)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildEnrichedUncorrectedFineRule)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildEnrichedCoarseRule)->Arg(34)->Arg(60)->Arg(200)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_HapticTick);
BENCHMARK(BM_SolveLocalModel)->Arg(34)->Arg(200)->Unit(benchmark::kMicrosecond);

/// Named registrations so that the solver reads as a word. The square run is the default unless
/// the default already is square (oversampling 1), in which case the second run is least-squares
/// collocation with oversampling 2 rather than the same run twice.
[[maybe_unused]] const bool registered = [] {
  const double default_oversampling = SprinklingSettings{}.oversampling;
  const std::vector<double> oversamplings = {default_oversampling, default_oversampling == 1.0 ? 2.0 : 1.0};
  for (const int n : build_node_counts)
    for (const SolverKind kind : solver_kinds) {
      const std::string tag = std::to_string(n) + "/" + touchstone::realtime::mfs::to_string(kind);
      for (const double oversampling : oversamplings) {
        std::ostringstream name;
        name << "BM_Build/" << tag << "/oversampling:" << oversampling
             << (oversampling == default_oversampling ? "(default)" : "");
        benchmark::RegisterBenchmark(name.str().c_str(), build, loop_settings(n, kind, oversampling))
            ->Unit(benchmark::kMillisecond)
            ->MinTime(build_min_time_s);
      }
      benchmark::RegisterBenchmark(("BM_AssembleAndSolve/" + tag).c_str(), assemble_and_solve, loop_settings(n, kind))
          ->Unit(benchmark::kMillisecond)
          ->MinTime(build_min_time_s);
    }
  return true;
}();

}  // namespace
