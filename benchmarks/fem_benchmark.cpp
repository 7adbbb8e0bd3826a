// FEM reference time against problem size (degrees of freedom; target: the paper's size,
// ~4045 nodes, ≤ 0.2 s end to end).
// Each case meshes B2 (R = 50 mm, a = 2.5 mm, frictionless) at a refinement level and solves it
// with each linear solver; assembly and solve times are reported as counters next to the dofs.
//
//   ./build/release/benchmarks/fem_benchmark                 # paper's size up to ~75K dofs
//   TOUCHSTONE_BENCH_LARGE=1 ./build/release/benchmarks/fem_benchmark   # adds ~520K dofs
//   mpirun -np 2 ./build/release/benchmarks/fem_benchmark    # the solves over two ranks (rank 0 reports)
#include "touchstone/fem/blas_kernels.hpp"
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <map>
#include <string>
#include <vector>

namespace {

using namespace touchstone;

/// The B2 geometry of studies/configs/b2_reference.toml at refinement `level`, meshed by rank 0
/// alone (under mpirun every rank would otherwise write the same file at once).
const std::string& b2_mesh(int level) {
  static std::map<int, std::string> paths;
  auto it = paths.find(level);
  if (it != paths.end()) return it->second;
  meshes::MeshParameters parameters;
  parameters.benchmark = meshes::Benchmark::B2;
  parameters.body_radius_m = 0.05;
  parameters.tool_radius_m = 0.0025;
  parameters.edge_size_m = 0.0025 / 4;
  parameters.size_growth = 0.5;
  parameters.max_size_m = 0.01;
  parameters.refinement = level;
  const std::string path = "fem_benchmark_b2_L" + std::to_string(level) + ".msh";
  if (fem::MpiSession::rank() == 0) meshes::generate_mesh(parameters, path);
  fem::MpiSession::barrier();
  return paths[level] = path;
}

void fem_solve(benchmark::State& state) {
  fem::ElasticityProblem problem;
  problem.mesh_path = b2_mesh(static_cast<int>(state.range(0)));
  problem.punch = fem::RigidPunch{2.5e-4, {0, 0, -1}, geometry::ContactCondition::frictionless};
  problem.solver.solver = static_cast<fem::LinearSolver>(state.range(1));
  fem::ElasticitySolution solution;
  double assembly = 0, solve = 0, setup = 0;
  for (auto _ : state) {
    solution = fem::solve_elasticity(problem);
    assembly += solution.assembly_s;
    solve += solution.solve_s;
    setup += solution.setup_s + solution.read_mesh_s;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["dofs"] = static_cast<double>(solution.dof_count);
  state.counters["fe_nodes"] = static_cast<double>(solution.node_count);
  state.counters["setup_s"] = setup / n;
  state.counters["assembly_s"] = assembly / n;
  state.counters["solve_s"] = solve / n;
  state.counters["iterations"] = solution.solver_iterations;
  state.SetLabel(solution.solver_name);
}

void register_cases() {
  const bool large = std::getenv("TOUCHSTONE_BENCH_LARGE") != nullptr;
  for (const auto solver : {fem::LinearSolver::cg_amg_trilinos, fem::LinearSolver::cg_gamg_petsc,
                            fem::LinearSolver::direct_mumps}) {
    for (int level = 0; level <= (large ? 2 : 1); ++level) {
      // MUMPS at ~520K P2 dofs needs tens of GB: iterative solvers only at the large end.
      if (level == 2 && solver == fem::LinearSolver::direct_mumps) continue;
      benchmark::RegisterBenchmark(("fem_solve/B2/L" + std::to_string(level) + "/" + fem::to_string(solver)).c_str(),
                                   fem_solve)
          ->Args({level, static_cast<long>(solver)})
          ->Unit(benchmark::kMillisecond)
          ->Iterations(1)
          ->Repetitions(level == 0 ? 5 : 3)
          ->ReportAggregatesOnly(true)
          ->UseRealTime();
    }
  }
}

/// Under mpirun every rank runs the cases (the solves are collective); only rank 0 prints them.
class SilentReporter : public benchmark::BenchmarkReporter {
 public:
  bool ReportContext(const Context&) override { return true; }
  void ReportRuns(const std::vector<Run>&) override {}
};

}  // namespace

int main(int argc, char** argv) {
  // The allocator settings of the program that runs the FEM (touchstone), so that the solves are
  // measured as it runs them: freed memory kept for reuse and the heap on transparent huge pages.
  realtime::runtime::keep_freed_memory_for_reuse();
  realtime::runtime::advise_huge_pages_for_heap();
  fem::MpiSession mpi(argc, argv);
  register_cases();
  // The direct solver's time depends on them (MpiSession has restarted the program if needed).
  const std::string blas = fem::loaded_openblas_core();
  benchmark::AddCustomContext("blas", blas.empty() ? "not OpenBLAS" : "OpenBLAS, " + blas + " kernels");
  benchmark::AddCustomContext("heap_huge_pages", realtime::runtime::heap_huge_pages_description());
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (fem::MpiSession::rank() == 0) {
    benchmark::RunSpecifiedBenchmarks();
  } else {
    SilentReporter silent;
    benchmark::RunSpecifiedBenchmarks(&silent);
  }
  benchmark::Shutdown();
  return 0;
}
