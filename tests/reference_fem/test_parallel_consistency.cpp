// Run under `mpirun -np 2`: the distributed solve must equal a serial solve of the same problem
// (each rank also solves alone on MPI_COMM_SELF) to 1e-8 relative, for every solver backend.
#include "fem_test_meshes.hpp"
#include "touchstone/fem/elasticity_problem.hpp"

#include <gtest/gtest.h>

namespace touchstone::fem {
namespace {

class ParallelConsistency : public ::testing::TestWithParam<LinearSolver> {};

void expect_distributed_equals_serial(const ElasticityProblem& problem) {
  const ElasticitySolution distributed = solve_elasticity(problem, MPI_COMM_WORLD);
  const ElasticitySolution serial = solve_elasticity(problem, MPI_COMM_SELF);
  EXPECT_EQ(distributed.mpi_processes, MpiSession::size());
  EXPECT_EQ(serial.mpi_processes, 1u);
  EXPECT_EQ(distributed.dof_count, serial.dof_count);

  const double tolerance = 1e-8;
  EXPECT_LT((distributed.force_N - serial.force_N).norm(), tolerance * serial.force_N.norm());
  EXPECT_NEAR(distributed.energy_J, serial.energy_J, tolerance * serial.energy_J);
  for (std::size_t p = 0; p < problem.probes.size(); ++p) {
    ASSERT_TRUE(distributed.probe_found[p] && serial.probe_found[p]);
    EXPECT_LT((distributed.probe_displacements_m[p] - serial.probe_displacements_m[p]).norm(),
              tolerance * serial.probe_displacements_m[p].norm())
        << "probe " << p;
  }
}

ElasticityProblem oblique_bonded_punch() {
  ElasticityProblem problem;
  problem.mesh_path = testing::coarse_hemisphere_mesh("parallel_hemisphere");
  problem.punch = RigidPunch{1.0e-4, Eigen::Vector3d(0.2, -0.1, -1.0), geometry::ContactCondition::bonded};
  problem.probes = {{0.0, 0.0, 0.045}, {0.01, 0.0, 0.03}, {0.0, 0.0, 0.049}};
  problem.solver.relative_tolerance = 1e-14;
  return problem;
}

TEST_P(ParallelConsistency, DistributedSolveEqualsSerialSolve) {
  ASSERT_GE(MpiSession::size(), 2u) << "run this test with mpirun -np 2";
  ElasticityProblem problem = oblique_bonded_punch();
  problem.solver.solver = GetParam();
  expect_distributed_equals_serial(problem);
}

// The condensed mixed formulation assembles and post-processes per owned cell like the
// displacement one: the same identity holds at ν = 0.499.
TEST(ParallelConsistencyMixed, DistributedSolveEqualsSerialSolve) {
  ASSERT_GE(MpiSession::size(), 2u) << "run this test with mpirun -np 2";
  ElasticityProblem problem = oblique_bonded_punch();
  problem.material.poisson_ratio = 0.499;
  problem.solver.formulation = Formulation::mixed_p0disc;
  problem.solver.solver = LinearSolver::direct_mumps;
  expect_distributed_equals_serial(problem);
}

INSTANTIATE_TEST_SUITE_P(Solvers, ParallelConsistency,
                         ::testing::Values(LinearSolver::cg_amg_trilinos, LinearSolver::cg_gamg_petsc,
                                           LinearSolver::direct_mumps),
                         [](const auto& info) { return to_string(info.param); });

}  // namespace
}  // namespace touchstone::fem
