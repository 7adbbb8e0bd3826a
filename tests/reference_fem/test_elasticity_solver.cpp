// Verification of the deal.II reference: patch tests, a manufactured solution with measured
// convergence order, the reaction/energy identity, and rejection of bad meshes.
#include "fem_test_meshes.hpp"
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/fem/tool_stiffness.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

namespace touchstone::fem {
namespace {


geometry::Material tissue() { return geometry::Material{10.0e3, 0.45}; }

class PatchTest : public ::testing::TestWithParam<unsigned int> {};

// An affine displacement prescribed on the whole boundary is reproduced to round-off inside.
TEST_P(PatchTest, AffineDirichletFieldIsReproduced) {
  ElasticityProblem problem = testing::affine_patch_problem(tissue(), false, "patch_cube");
  problem.solver.degree = GetParam();
  problem.solver.relative_tolerance = 1e-13;
  const ElasticitySolution solution = solve_elasticity(problem);
  for (std::size_t p = 0; p < problem.probes.size(); ++p) {
    ASSERT_TRUE(solution.probe_found[p]);
    const Eigen::Vector3d exact = testing::affine_field(problem.probes[p]);
    EXPECT_LT((solution.probe_displacements_m[p] - exact).norm(), 1e-10 * exact.norm()) << "probe " << p;
  }
  EXPECT_LT(solution.l2_error_m, 1e-11);
}

// The direct solver: MUMPS orders the matrix as asked (approximate minimum degree, which this
// PETSc drops when it is set on the factor matrix instead of its options database), the name
// records the ordering MUMPS reports it used, and the affine field stays exact.
TEST(DirectSolver, MumpsUsesTheOrderingItAsksForAndNamesIt) {
  ElasticityProblem problem = testing::affine_patch_problem(tissue(), false, "direct_patch_cube");
  problem.solver.solver = LinearSolver::direct_mumps;
  const ElasticitySolution solution = solve_elasticity(problem);
  EXPECT_NE(solution.solver_name.find("AMD ordering"), std::string::npos) << solution.solver_name;
  for (std::size_t p = 0; p < problem.probes.size(); ++p) {
    ASSERT_TRUE(solution.probe_found[p]);
    const Eigen::Vector3d exact = testing::affine_field(problem.probes[p]);
    EXPECT_LT((solution.probe_displacements_m[p] - exact).norm(), 1e-10 * exact.norm()) << "probe " << p;
  }
}

// The same field with tractions σ(u)·n on three faces: exercises the traction assembly.
TEST_P(PatchTest, AffineFieldWithTractionFacesIsReproduced) {
  ElasticityProblem problem = testing::affine_patch_problem(tissue(), true, "patch_cube");
  problem.solver.degree = GetParam();
  problem.solver.relative_tolerance = 1e-13;
  const ElasticitySolution solution = solve_elasticity(problem);
  EXPECT_LT(solution.l2_error_m, 1e-11);
}

INSTANTIATE_TEST_SUITE_P(Degrees, PatchTest, ::testing::Values(1u, 2u));

/// u = s (sin ax + sin ay, sin ay + sin az, sin az + sin ax): a curl-free plus a
/// divergence-free part, so both λ+2μ and μ are exercised. b = −div σ(u).
struct Manufactured {
  double a = 2.0, s = 1.0e-3;
  double lambda, mu;
  Eigen::Vector3d u(const Eigen::Vector3d& x) const {
    return s * Eigen::Vector3d(std::sin(a * x[0]) + std::sin(a * x[1]), std::sin(a * x[1]) + std::sin(a * x[2]),
                               std::sin(a * x[2]) + std::sin(a * x[0]));
  }
  Eigen::Matrix3d gradient(const Eigen::Vector3d& x) const {  // (∇u)_ij = ∂u_i/∂x_j
    const double cx = a * std::cos(a * x[0]), cy = a * std::cos(a * x[1]), cz = a * std::cos(a * x[2]);
    Eigen::Matrix3d g;
    g << cx, cy, 0, 0, cy, cz, cx, 0, cz;
    return s * g;
  }
  Eigen::Vector3d body_force(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d curl_free(std::sin(a * x[0]), std::sin(a * x[1]), std::sin(a * x[2]));
    const Eigen::Vector3d div_free(std::sin(a * x[1]), std::sin(a * x[2]), std::sin(a * x[0]));
    return s * a * a * ((lambda + 2 * mu) * curl_free + mu * div_free);
  }
  Eigen::Vector3d traction(const Eigen::Vector3d& x, const Eigen::Vector3d& n) const {
    const Eigen::Matrix3d e = 0.5 * (gradient(x) + gradient(x).transpose());
    return (lambda * e.trace() * Eigen::Matrix3d::Identity() + 2 * mu * e) * n;
  }
};

double manufactured_l2_error(unsigned int degree, double h, const std::string& mesh_name) {
  const geometry::Material material = tissue();
  const Manufactured m{2.0, 1.0e-3, material.lame_lambda_Pa(), material.shear_modulus_Pa()};
  ElasticityProblem problem = testing::manufactured_cube_problem(m, material, h, mesh_name);
  problem.solver.degree = degree;
  problem.solver.relative_tolerance = 1e-12;
  return solve_elasticity(problem).l2_error_m;
}

// On unstructured meshes whose size halves, the L2 error falls as h^(k+1).
TEST(ManufacturedSolution, ConvergenceOrderMatchesElementDegree) {
  const std::vector<double> sizes{0.4, 0.2, 0.1};
  for (const unsigned int degree : {1u, 2u}) {
    std::vector<double> errors;
    for (std::size_t i = 0; i < sizes.size(); ++i)
      errors.push_back(manufactured_l2_error(degree, sizes[i], "mms_cube_" + std::to_string(i)));
    const double order = std::log(errors[1] / errors[2]) / std::log(sizes[1] / sizes[2]);
    if (MpiSession::rank() == 0)
      std::printf("  P%u: L2 errors %.3e %.3e %.3e, observed order %.2f (expected %u)\n", degree,
                  errors[0], errors[1], errors[2], order, degree + 1);
    EXPECT_NEAR(order, degree + 1.0, 0.3) << "P" << degree;
  }
}

class PunchTest : public ::testing::TestWithParam<geometry::ContactCondition> {};

// F·(δd) = uᵀKu = 2U: the reaction from the residual and the force from the energy are two
// different computations that must agree (to the solver tolerance).
TEST_P(PunchTest, ResidualForceEqualsEnergyForce) {
  ElasticityProblem problem;
  problem.mesh_path = testing::coarse_hemisphere_mesh("punch_hemisphere");
  problem.material = tissue();
  problem.punch = RigidPunch{1.0e-4, {0.0, 0.0, -1.0}, GetParam()};
  problem.solver.relative_tolerance = 1e-12;
  const ElasticitySolution solution = solve_elasticity(problem);
  const double axial = -solution.force_N[2];
  EXPECT_GT(axial, 0);
  EXPECT_NEAR(axial, solution.energy_force_N, 1e-7 * axial);
  // Axisymmetric problem on an unstructured coarse mesh: the lateral force is a small
  // discretisation artefact.
  EXPECT_LT(std::hypot(solution.force_N[0], solution.force_N[1]), 1e-2 * axial);
}

// Frictionless along an oblique axis: the constraint u·d = δ is honoured and the reaction is
// parallel to d (tangential traction free).
TEST(PunchTest, ObliqueFrictionlessReactionIsAlongTheAxis) {
  ElasticityProblem problem;
  problem.mesh_path = testing::coarse_hemisphere_mesh("punch_hemisphere");
  problem.material = tissue();
  const Eigen::Vector3d d = Eigen::Vector3d(0.3, 0.0, -1.0).normalized();
  problem.punch = RigidPunch{1.0e-4, d, geometry::ContactCondition::frictionless};
  problem.probes = {{0.0, 0.0, 0.05}, {0.002, 0.001, std::sqrt(0.05 * 0.05 - 0.002 * 0.002 - 0.001 * 0.001)}};
  problem.solver.relative_tolerance = 1e-12;
  const ElasticitySolution solution = solve_elasticity(problem);
  const Eigen::Vector3d f = solution.force_N;
  EXPECT_LT((f - f.dot(d) * d).norm(), 1e-6 * f.norm());
  EXPECT_NEAR(f.dot(d), solution.energy_force_N, 1e-7 * f.norm());
  // The constraint holds at the patch nodes; the probes lie on the sphere, up to the sag
  // s = h²/(8R) of the flat faces (h = 2.5 mm) away from them, where u varies by about s δ / a.
  const double sag = 0.0025 * 0.0025 / (8 * 0.05);
  for (std::size_t p = 0; p < problem.probes.size(); ++p) {
    ASSERT_TRUE(solution.probe_found[p]);
    EXPECT_NEAR(solution.probe_displacements_m[p].dot(d), 1.0e-4, sag * 1.0e-4 / 0.005);
  }
}

// Superposition: the tool stiffness from unit solves gives the force of any displacement. A
// direct solve at an oblique displacement must equal K U to the solver tolerance; bonded K is
// symmetric (reciprocity), which the three independent solves do not impose.
TEST(ToolStiffness, UnitSolvesPredictAnObliqueSolve) {
  ElasticityProblem problem;
  problem.mesh_path = testing::coarse_hemisphere_mesh("punch_hemisphere");
  problem.material = tissue();
  problem.solver.relative_tolerance = 1e-12;
  const Eigen::Vector3d oblique = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  const double depth = 1.5e-4;

  problem.punch = RigidPunch{1.0e-4, {0.0, 0.0, -1.0}, geometry::ContactCondition::bonded};
  const ToolStiffness bonded = solve_tool_stiffness(problem);
  EXPECT_EQ(bonded.solves, 3u);
  const Eigen::Matrix3d& k = bonded.force_per_displacement_N_per_m;
  EXPECT_LT((k - k.transpose()).norm(), 1e-8 * k.norm());
  problem.punch = RigidPunch{depth, oblique, geometry::ContactCondition::bonded};
  const Eigen::Vector3d direct_bonded = solve_elasticity(problem).force_N;
  EXPECT_LT((bonded.force_N(depth * oblique) - direct_bonded).norm(), 1e-8 * direct_bonded.norm());

  problem.punch = RigidPunch{1.0e-4, oblique, geometry::ContactCondition::frictionless};
  const ToolStiffness frictionless = solve_tool_stiffness(problem);
  EXPECT_EQ(frictionless.solves, 1u);
  problem.punch = RigidPunch{depth, oblique, geometry::ContactCondition::frictionless};
  const Eigen::Vector3d direct_frictionless = solve_elasticity(problem).force_N;
  // A displacement across the axis adds nothing: the patch slides freely.
  const Eigen::Vector3d across = oblique.cross(Eigen::Vector3d::UnitX()).normalized();
  EXPECT_LT((frictionless.force_N(depth * oblique + 3e-5 * across) - direct_frictionless).norm(), 1e-8 * direct_frictionless.norm());
  // The bonded patch is one of the frictionless problem's admissible fields (u = δ d satisfies
  // u·d = δ), so the frictionless energy, F·d δ / 2, cannot exceed the bonded one.
  EXPECT_LT(direct_frictionless.dot(oblique), direct_bonded.dot(oblique));
}

INSTANTIATE_TEST_SUITE_P(Contacts, PunchTest, ::testing::Values(geometry::ContactCondition::frictionless, geometry::ContactCondition::bonded),
                         [](const auto& info) { return to_string(info.param); });

TEST(ElasticitySolverInput, MissingBoundaryIsNamed) {
  ElasticityProblem problem;
  problem.mesh_path = testing::unit_cube_mesh(0.5, "input_cube");
  problem.punch = RigidPunch{};
  try {
    solve_elasticity(problem);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("tool_patch"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("input_cube"), std::string::npos) << e.what();
  }
}

TEST(ElasticitySolverInput, UnreadableMeshIsNamed) {
  if (MpiSession::rank() == 0) std::ofstream("garbage.msh") << "$MeshFormat\nnot a mesh\n";
  MpiSession::barrier();
  ElasticityProblem problem;
  problem.mesh_path = "garbage.msh";
  EXPECT_THROW(
      {
        try {
          solve_elasticity(problem);
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find("garbage.msh"), std::string::npos) << e.what();
          throw;
        }
      },
      std::runtime_error);
  problem.mesh_path = "does_not_exist.msh";
  EXPECT_THROW(solve_elasticity(problem), std::runtime_error);
}

TEST(ElasticitySolverInput, InvalidParametersAreRejected) {
  ElasticityProblem problem;
  problem.mesh_path = "unused.msh";
  problem.material.poisson_ratio = 0.5;
  EXPECT_THROW(solve_elasticity(problem), std::invalid_argument);
  problem.material = tissue();
  problem.material.youngs_modulus_Pa = -1;
  EXPECT_THROW(solve_elasticity(problem), std::invalid_argument);
  problem.material = tissue();
  problem.punch = RigidPunch{std::nan(""), {0, 0, -1}, geometry::ContactCondition::bonded};
  EXPECT_THROW(solve_elasticity(problem), std::invalid_argument);
}

}  // namespace
}  // namespace touchstone::fem
