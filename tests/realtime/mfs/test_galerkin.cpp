// The Galerkin MFS (galerkin.hpp): K is symmetric positive definite, the tool's penalty force
// balances the cut's exactly (the shape functions are a partition of unity, so a rigid
// translation is a test function), and on B3 the force converges to the FEM from above as N
// grows, the energy force approaching the reaction — what point collocation does not do
// (test_force_methods).
#include "hemisphere_fixture.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double depth_m = 0.25e-3;
constexpr double fem_reference_N = 0.022038;  // touchstone fem studies/configs/b3_reference.toml, frictionless

using testing::hemisphere;
using testing::pole_contact;

LocalModelSettings galerkin_settings(int node_count) {
  LocalModelSettings s;
  s.formulation = Formulation::galerkin;
  s.formulation = Formulation::galerkin;
  s.sprinkling.node_count = node_count;
  s.sprinkling.oversampling = 1;
  s.force.haptic_method = ForceMethod::reaction;
  return s;
}

TEST(Galerkin, StiffnessIsSymmetricAndTheToolBalancesTheCut) {
  for (const Constraint constraint : {Constraint::penalty, Constraint::nitsche})
  for (const geometry::ContactCondition condition : {geometry::ContactCondition::frictionless, geometry::ContactCondition::bonded}) {
    SCOPED_TRACE(to_string(constraint));
    LocalModelSettings settings = galerkin_settings(60);
    settings.galerkin.constraint = constraint;
    const LocalModel model = build_local_model(hemisphere(), pole_contact(condition), geometry::Material{}, settings);
    ASSERT_TRUE(model.ok()) << model.status;
    const Eigen::MatrixXd& k = model.galerkin.stiffness;
    EXPECT_LT((k - k.transpose()).norm(), 1e-12 * k.norm());
    const Eigen::Vector3d push(2e-5, -1e-5, -2.5e-4);
    const LocalSolution solution = solve_local_model(model, push);
    ASSERT_EQ(solution.status, "ok");
    // Force on the tissue through the patch = the cut's reaction (no body force): a rigid
    // translation is a test function, with Nitsche's flux terms as with the penalty.
    const Eigen::Vector3d patch_force =
        model.galerkin.patch_tool_map * push - model.galerkin.patch_map * solution.parameters;
    EXPECT_LT((patch_force - solution.forces.reaction_N).norm(), 1e-9 * patch_force.norm());
    EXPECT_LT((solution.forces.haptic_N - solution.forces.reaction_N).norm(), 1e-9 * patch_force.norm());
    // Penalty: the work of the tool is the strain energy plus the penalty's, F·U ≥ 2U.
    if (constraint == Constraint::penalty) {
      EXPECT_GT(solution.forces.reaction_N.dot(push), 2 * solution.forces.energy_J * (1 - 1e-9));
    }
  }
}

TEST(Galerkin, PatchNodeRowsAreTheConstraintTractionWeightedByTheirShapeFunctions) {
  // Eq. 9 in the weak form (local_model's paper_map): a patch node's elastic row applied to the
  // solution, (K_el U)_a, is ∫_patch h_a λ dA with λ = α P (U_tool − u_h) the penalty traction —
  // computed here independently from the patch quadrature and the MLS values.
  const LocalModelSettings settings = galerkin_settings(100);
  const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  const Eigen::Vector3d push = depth_m * pole_contact().direction;
  const LocalSolution solution = solve_local_model(model, push);
  ASSERT_EQ(solution.status, "ok");
  const GalerkinSystem& g = model.galerkin;
  ASSERT_GE(g.patch_nodes.size(), 8u);
  const PatchQuadrature patch =
      patch_quadrature(hemisphere(), pole_contact(), settings.force.patch_radial_points, settings.force.patch_angular_points);
  const Eigen::Vector3d d = pole_contact().direction;
  std::vector<Eigen::Vector3d> expected(g.patch_nodes.size(), Eigen::Vector3d::Zero());
  std::vector<double> shape_integral(g.patch_nodes.size(), 0.0);
  Eigen::MatrixXd mass = Eigen::MatrixXd::Zero(g.patch_node_mass_m2.rows(), g.patch_node_mass_m2.cols());
  MlsEvaluation mls;
  for (std::size_t q = 0; q < patch.points.size(); ++q) {
    evaluate_mls(patch.points[q], model.cloud.positions, model.cloud.radii, {}, settings.collocation.mls,
                 Derivatives::values, mls);
    ASSERT_EQ(mls.status, MlsStatus::ok);
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    for (std::size_t b = 0; b < mls.neighbours.size(); ++b)
      u += mls.value[b] * solution.parameters.segment<3>(3 * mls.neighbours[b]);
    const Eigen::Vector3d traction = g.penalty_Pa_per_m * d * d.dot(push - u);  // frictionless: P = d dᵀ
    for (std::size_t i = 0; i < g.patch_nodes.size(); ++i)
      for (std::size_t b = 0; b < mls.neighbours.size(); ++b)
        if (mls.neighbours[b] == g.patch_nodes[i]) {
          expected[i] += patch.weights[q] * mls.value[b] * traction;
          shape_integral[i] += patch.weights[q] * mls.value[b];
          for (std::size_t j = 0; j < g.patch_nodes.size(); ++j)
            for (std::size_t c = 0; c < mls.neighbours.size(); ++c)
              if (mls.neighbours[c] == g.patch_nodes[j]) mass(i, j) += patch.weights[q] * mls.value[b] * mls.value[c];
        }
  }
  double largest = 0;
  for (const Eigen::Vector3d& e : expected) largest = std::max(largest, e.norm());
  ASSERT_GT(largest, 0.0);
  for (std::size_t i = 0; i < g.patch_nodes.size(); ++i) {
    const Eigen::Vector3d row_force = g.patch_node_rows.middleRows<3>(3 * static_cast<Eigen::Index>(i)) * solution.parameters;
    EXPECT_LT((row_force - expected[i]).norm(), 1e-7 * largest) << "patch node " << g.patch_nodes[i];
    EXPECT_NEAR(g.patch_node_shape_integral_m2[i], shape_integral[i], 1e-12 * shape_integral[i]);
  }
  EXPECT_LT((g.patch_node_mass_m2 - mass).norm(), 1e-12 * mass.norm());
}

TEST(Galerkin, ForceConvergesToTheFemFromAbove) {
  // Measured on this surface: reaction +259 %, +59 %, +22 % and energy +184 %, +39 %, +18 % at
  // N = 33, 103, 409 (touchstone mfs studies/configs/mfs_b3_galerkin.toml continues the series to
  // N ≈ 800).
  std::vector<double> reaction, energy;
  for (const int n : {34, 100, 400}) {
    const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, galerkin_settings(n));
    ASSERT_TRUE(model.ok()) << model.status;
    const LocalSolution solution = solve_local_model(model, depth_m * pole_contact().direction);
    ASSERT_EQ(solution.status, "ok");
    reaction.push_back(solution.forces.reaction_N.dot(pole_contact().direction));
    energy.push_back(solution.forces.energy_force_N);
    std::printf("  N = %zu: reaction %.4e N (%+.1f %%), energy %.4e N (%+.1f %%)\n", model.cloud.size(), reaction.back(),
                100 * (reaction.back() / fem_reference_N - 1), energy.back(), 100 * (energy.back() / fem_reference_N - 1));
  }
  for (std::size_t k = 0; k < reaction.size(); ++k) {
    EXPECT_GT(reaction[k], fem_reference_N) << "a penalty-constrained Galerkin model is stiffer than the limit";
    if (k > 0) {
      EXPECT_LT(reaction[k], reaction[k - 1]);
      EXPECT_LT(energy[k], energy[k - 1]);
      EXPECT_LT(reaction[k] / energy[k], reaction[k - 1] / energy[k - 1]) << "the two methods approach each other";
    }
  }
  EXPECT_LT(reaction.back(), 1.25 * fem_reference_N);
}

}  // namespace
}  // namespace touchstone::realtime::mfs
