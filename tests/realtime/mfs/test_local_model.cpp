// The local MFS model: degenerate input ends in a clear status or a named
// std::invalid_argument, never in NaN (coplanar or duplicate nodes, too small supports and
// their adaptive rescue, ν → 0.5, NaN coordinates, invalid settings); the 3×3 tool stiffness K_t
// that gives the exact force at haptic rate is the condensation of the collocation system and
// the model is linear; the paper mode solves eqs. 7–8 with the tip's parameters set to U_tool;
// least-squares collocation reports the misfit of its rectangular system and solves its normal
// equations.
#include "hemisphere_fixture.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

const double nan = std::numeric_limits<double>::quiet_NaN();

using testing::hemisphere;
using testing::pole_contact;

/// Least-squares collocation (these tests are about its rows, solvers and maps) at N ≈ 60
/// without the (slow, study-only) energy quadrature.
LocalModelSettings small_settings() {
  LocalModelSettings s;
  s.formulation = Formulation::collocation;
  s.force.haptic_method = default_haptic_method(s.formulation, false);
  s.sprinkling.node_count = 60;
  s.force.energy = false;
  return s;
}

/// Runs `call`, expects std::invalid_argument whose what() contains `field`.
template <class Call>
void expect_invalid_argument_naming(Call call, const std::string& field) {
  try {
    call();
    ADD_FAILURE() << "expected std::invalid_argument naming " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << "what() = " << e.what();
  }
}

bool all_finite(const ToolForces& f) {
  return f.traction_integral_N.allFinite() && f.reaction_N.allFinite() && f.paper_partition_N.allFinite() &&
         std::isfinite(f.energy_J) && std::isfinite(f.energy_force_N) && f.paper_tip_residual_Pa.allFinite() &&
         f.haptic_N.allFinite();
}

/// Nothing non-finite in what an assembly returned (the sparse values, both right-hand sides,
/// the row scaling and the reported rcond and growth).
void expect_no_nan(const CollocationSystem& system) {
  for (Eigen::Index k = 0; k < system.stiffness.nonZeros(); ++k)
    ASSERT_TRUE(std::isfinite(system.stiffness.valuePtr()[k])) << "K entry " << k;
  EXPECT_TRUE(system.constant_rhs.allFinite());
  EXPECT_TRUE(system.tool_rhs.allFinite());
  EXPECT_TRUE(system.row_scale.allFinite());
  EXPECT_TRUE(std::isfinite(system.status.min_rcond));
  EXPECT_TRUE(std::isfinite(system.status.max_support_scale));
}

// ---------------------------------------------------------------------------------------------
// Hand-made clouds.

constexpr double side_m = 0.01;  // a 10 mm cube

/// The affine field u = G x + c, which MLS with either basis reproduces exactly.
Eigen::Matrix3d affine_gradient() {
  Eigen::Matrix3d g;
  g << 1.0e-2, 2.0e-3, -3.0e-3, 5.0e-3, -2.0e-2, 1.0e-3, -4.0e-3, 3.0e-3, 1.5e-2;
  return g;
}
const Eigen::Vector3d affine_offset(1.0e-5, -2.0e-5, 3.0e-5);
Eigen::Vector3d affine(const Eigen::Vector3d& x) { return affine_gradient() * x + affine_offset; }

/// A jittered n³ lattice on the cube with the affine field as Dirichlet data on every boundary
/// node and Navier rows (no body force) inside. Support radius = factor × spacing.
NodeCloud box_cloud(int n, double factor, unsigned seed = 3) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  const double h = side_m / (n - 1);
  NodeCloud cloud;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const int index[3] = {i, j, k};
        Eigen::Vector3d x, normal = Eigen::Vector3d::Zero();
        bool boundary = false;
        for (int d = 0; d < 3; ++d) {
          const bool low = index[d] == 0, high = index[d] == n - 1;
          x[d] = index[d] * h + ((low || high) ? 0.0 : jitter(random) * h);
          if (low || high) {
            boundary = true;
            normal[d] = high ? 1.0 : -1.0;
          }
        }
        std::array<CollocationRow, 3> rows;
        for (int d = 0; d < 3; ++d) {
          rows[d].direction = Eigen::Vector3d::Unit(d);
          rows[d].type = boundary ? CollocationRow::Type::dirichlet : CollocationRow::Type::navier;
          rows[d].value = boundary ? affine(x)[d] : 0.0;
        }
        cloud.positions.push_back(x);
        cloud.radii.push_back(factor * h);
        cloud.kinds.push_back(boundary ? NodeKind::cut : NodeKind::interior);
        cloud.normals.push_back(boundary ? Eigen::Vector3d(normal.normalized()) : Eigen::Vector3d::Zero());
        cloud.rows.push_back(rows);
        cloud.spacing.push_back(h);
      }
  return cloud;
}

/// Appends a copy of node j (same position, radius, rows).
void duplicate_node(NodeCloud& cloud, int j) {
  cloud.positions.push_back(cloud.positions[j]);
  cloud.radii.push_back(cloud.radii[j]);
  cloud.kinds.push_back(cloud.kinds[j]);
  cloud.normals.push_back(cloud.normals[j]);
  cloud.rows.push_back(cloud.rows[j]);
  cloud.spacing.push_back(cloud.spacing[j]);
}

/// Max |u_h − u_affine| over the nodes, relative to max |u_affine|; NaN if u_h cannot be evaluated.
double affine_error(const NodeCloud& cloud, const Eigen::VectorXd& parameters, const MlsSettings& mls) {
  MlsEvaluation scratch;
  double error = 0, scale = 0;
  for (std::size_t j = 0; j < cloud.size(); ++j) {
    Eigen::Vector3d u;
    if (evaluate_displacement(cloud, parameters, cloud.positions[j], mls, scratch, u) != MlsStatus::ok) return nan;
    error = std::max(error, (u - affine(cloud.positions[j])).norm());
    scale = std::max(scale, affine(cloud.positions[j]).norm());
  }
  return error / scale;
}

// ---------------------------------------------------------------------------------------------
// A. Degenerate input.

// All nodes in the plane z = 0: the moment matrix has a zero z row with either basis.
TEST(LocalModelDegenerate, CoplanarNodesAreSingularMoments) {
  const double h = 1e-3;
  NodeCloud cloud;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) {
      cloud.positions.emplace_back(i * h, j * h, 0.0);
      cloud.radii.push_back(3.5 * h);  // ≥ 10 nodes in every support, even at the corners
      cloud.kinds.push_back(NodeKind::interior);
      cloud.normals.emplace_back(Eigen::Vector3d::Zero());
      std::array<CollocationRow, 3> rows;
      for (int d = 0; d < 3; ++d) rows[d].direction = Eigen::Vector3d::Unit(d);
      cloud.rows.push_back(rows);
      cloud.spacing.push_back(h);
    }
  const geometry::Material material;
  for (const Basis basis : {Basis::quadratic, Basis::linear})
    for (const double growth : {1.0, 2.0}) {
      SCOPED_TRACE(::testing::Message() << "basis " << basis_size(basis) << " growth " << growth);
      CollocationSettings settings;
      settings.mls.basis = basis;
      settings.mls.max_support_scale = growth;  // growing the supports cannot leave the plane
      CollocationSystem system;
      assemble_collocation(cloud, material, settings, system);
      EXPECT_EQ(system.status.mls, MlsStatus::singular_moments);
      EXPECT_EQ(system.status.node, 0);
      EXPECT_EQ(system.stiffness.nonZeros(), 0);
      EXPECT_LE(system.status.max_support_scale, growth);
      expect_no_nan(system);
    }
}

// Two nodes at the same position with the same radius have identical shape functions, so K has
// two identical 3-column blocks (and two identical 3-row blocks): singular. Either the solver
// says so, or the answer it gives is finite and the field u_h = Σ h_J u_J (which does not see
// how the pair shares its parameters) is still the exact affine field. Measured: dense LU reports
// the singular K; GMRES-ILUT converges to the exact field; sparse LU factorises (rounding leaves
// tiny, non-zero pivots) and its answer is wrong by orders of magnitude, so the solve's residual
// check must refuse it rather than report it as fine.
TEST(LocalModelDegenerate, DuplicateNodesAreReportedOrHarmlessNeverNaN) {
  const geometry::Material material;
  NodeCloud cloud = box_cloud(5, 2.6);
  const int interior = 2 * 25 + 2 * 5 + 2;  // the centre node
  duplicate_node(cloud, interior);
  CollocationSettings settings;
  CollocationSystem system;
  assemble_collocation(cloud, material, settings, system);
  ASSERT_TRUE(system.status.ok()) << "the shape functions themselves are fine with a duplicate";
  expect_no_nan(system);
  for (const SolverKind kind : {SolverKind::dense_lu, SolverKind::sparse_lu, SolverKind::gmres_ilut}) {
    SCOPED_TRACE(to_string(kind));
    CollocationSolver solver(SolverSettings{kind});
    const SolveReport factorised = solver.factorize(system.stiffness);
    if (!factorised.ok) {
      std::printf("  duplicate node, %s: factorisation reports \"%s\"\n", to_string(kind).c_str(),
                  factorised.failure.c_str());
      EXPECT_FALSE(factorised.failure.empty());
      continue;
    }
    Eigen::MatrixXd parameters;
    const SolveReport solved = solver.solve(system.constant_rhs, parameters);
    if (!solved.ok) {
      std::printf("  duplicate node, %s: solve reports \"%s\"\n", to_string(kind).c_str(), solved.failure.c_str());
      EXPECT_FALSE(solved.failure.empty());
      continue;
    }
    ASSERT_TRUE(parameters.allFinite());
    const double error = affine_error(cloud, parameters.col(0), settings.mls);
    std::printf("  duplicate node, %s: solved, relative residual %.2e, affine field error %.2e, "
                "|u_dup - u_centre| = %.2e m\n",
                to_string(kind).c_str(), solved.relative_residual, error,
                (parameters.col(0).segment<3>(3 * interior) - parameters.col(0).tail<3>()).norm());
    EXPECT_LT(solved.relative_residual, 1e-8) << "ok = true, yet K x != f";
    EXPECT_LT(error, 1e-6) << "ok = true, yet u_h is not the affine field";
  }
}

// A node far from every other one has only itself in its support: too few nodes there, and the
// status names it. With tiny radii everywhere the very first node fails.
TEST(LocalModelDegenerate, TooFewNodesNamesTheNode) {
  const geometry::Material material;
  CollocationSettings settings;
  {
    NodeCloud cloud = box_cloud(5, 2.6);
    duplicate_node(cloud, 0);
    const int lonely = static_cast<int>(cloud.size()) - 1;
    cloud.positions[lonely] = Eigen::Vector3d(0.1, 0.1, 0.1);  // 10 cube sides away
    CollocationSystem system;
    assemble_collocation(cloud, material, settings, system);
    EXPECT_EQ(system.status.mls, MlsStatus::too_few_nodes);
    EXPECT_EQ(system.status.node, lonely);
    expect_no_nan(system);
  }
  {
    const NodeCloud cloud = box_cloud(5, 0.5);  // nearest neighbour ≥ 0.6 h away: alone
    CollocationSystem system;
    assemble_collocation(cloud, material, settings, system);
    EXPECT_EQ(system.status.mls, MlsStatus::too_few_nodes);
    EXPECT_EQ(system.status.node, 0);
    expect_no_nan(system);
  }
}

// Radius 1.6 h: a corner node of the lattice sees itself, 3 edge and ≤ 3 face neighbours — fewer
// than the 10 quadratic terms. Growth up to 2× rescues it, and the rescued system is still
// consistent (it reproduces the affine field).
TEST(LocalModelDegenerate, AdaptiveGrowthRescuesSmallSupports) {
  const geometry::Material material;
  const NodeCloud cloud = box_cloud(6, 1.6);
  CollocationSettings settings;
  settings.mls.max_support_scale = 1;
  CollocationSystem system;
  assemble_collocation(cloud, material, settings, system);
  EXPECT_EQ(system.status.mls, MlsStatus::too_few_nodes) << "without growth the radius is too small";

  settings.mls.max_support_scale = 2;
  assemble_collocation(cloud, material, settings, system);
  ASSERT_TRUE(system.status.ok()) << "node " << system.status.node;
  EXPECT_GT(system.status.max_support_scale, 1.0);
  EXPECT_LE(system.status.max_support_scale, 2.0);
  expect_no_nan(system);
  CollocationSolver solver;
  ASSERT_TRUE(solver.factorize(system.stiffness).ok);
  Eigen::MatrixXd parameters;
  ASSERT_TRUE(solver.solve(system.constant_rhs, parameters).ok);
  EXPECT_LT(affine_error(cloud, parameters.col(0), settings.mls), 1e-8);
}

TEST(LocalModelDegenerate, InvalidMaterialIsNamed) {
  const LocalModelSettings settings = small_settings();
  const auto build = [&](double e, double nu) {
    return [&settings, e, nu] { build_local_model(hemisphere(), pole_contact(), geometry::Material{e, nu}, settings); };
  };
  expect_invalid_argument_naming(build(10e3, 0.5), "poisson_ratio");
  expect_invalid_argument_naming(build(10e3, 0.6), "poisson_ratio");
  expect_invalid_argument_naming(build(10e3, -0.1), "poisson_ratio");
  expect_invalid_argument_naming(build(10e3, nan), "poisson_ratio");
  expect_invalid_argument_naming(build(nan, 0.45), "youngs_modulus_Pa");
  expect_invalid_argument_naming(build(0.0, 0.45), "youngs_modulus_Pa");
  expect_invalid_argument_naming(build(-10e3, 0.45), "youngs_modulus_Pa");
}

// Nearly incompressible: λ = Eν/((1+ν)(1−2ν)) grows like 1/(1−2ν), but the model is still built,
// solved accurately, and its forces are finite. Finite is not right: measured at N = 57, ν = 0.499
// gives 1.30× the ν = 0.45 push force, ν = 0.49999 (λ/μ = 5·10⁴) −27× (the wrong sign) — the
// strong form amplifies the discretisation error of div u by λ.
TEST(LocalModelDegenerate, NearlyIncompressibleForcesAreFinite) {
  const LocalModelSettings settings = small_settings();
  const Eigen::Vector3d push = 1e-4 * pole_contact().direction;
  const LocalModel reference = build_local_model(hemisphere(), pole_contact(), geometry::Material{10e3, 0.45}, settings);
  ASSERT_TRUE(reference.ok()) << reference.status;
  const LocalSolution at_045 = solve_local_model(reference, push);
  ASSERT_EQ(at_045.status, "ok");
  const double f_045 = at_045.forces.haptic_N.dot(pole_contact().direction);
  for (const double nu : {0.499, 0.49999}) {
    SCOPED_TRACE(nu);
    const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{10e3, nu}, settings);
    if (!model.ok()) {
      // Least squares squares the condition number: at λ/μ = 5·10⁴ the normal equations may
      // be refused, which must say so.
      EXPECT_NE(model.status.find("ill-conditioned"), std::string::npos) << model.status;
      std::printf("  nu = %.5f: model refused: %s\n", nu, model.status.c_str());
      continue;
    }
    EXPECT_TRUE(model.tool_stiffness_N_per_m.allFinite());
    const LocalSolution solution = solve_local_model(model, push);
    EXPECT_EQ(solution.status, "ok");
    EXPECT_TRUE(all_finite(solution.forces));
    EXPECT_TRUE(solution.parameters.allFinite());
    // The solve itself stays accurate (the normal equations of the least-squares system hold):
    // what changes is the discretisation.
    const Eigen::VectorXd rhs = model.system.constant_rhs + model.system.tool_rhs * push;
    const Eigen::SparseMatrix<double> k = model.system.stiffness;
    const double optimality = (k.transpose() * (k * solution.parameters - rhs)).norm() / (k.transpose() * rhs).norm();
    EXPECT_LT(optimality, 1e-6);
    const double f = solution.forces.haptic_N.dot(pole_contact().direction);
    std::printf("  nu = %.5f: normal-equation residual %.3e; push force %.6e N (traction %.6e, reaction %.6e, paper %.6e), "
                "%.4f x the nu = 0.45 force %.6e N\n",
                nu, optimality, f, solution.forces.traction_integral_N.dot(pole_contact().direction),
                solution.forces.reaction_N.dot(pole_contact().direction),
                solution.forces.paper_partition_N.dot(pole_contact().direction), f / f_045, f_045);
  }
}

TEST(LocalModelDegenerate, NanCoordinatesAreReported) {
  const geometry::Material material;
  // A node with a NaN coordinate (or radius): every collocation point sees an invalid candidate.
  for (const bool radius : {false, true}) {
    NodeCloud cloud = box_cloud(4, 2.6);
    (radius ? cloud.radii[7] : cloud.positions[7].y()) = nan;
    CollocationSystem system;
    assemble_collocation(cloud, material, CollocationSettings{}, system);
    EXPECT_EQ(system.status.mls, MlsStatus::non_finite_input) << (radius ? "radius" : "position");
    EXPECT_GE(system.status.node, 0);
    EXPECT_EQ(system.stiffness.nonZeros(), 0);
    expect_no_nan(system);
  }

  const LocalModelSettings settings = small_settings();
  ToolContact contact = pole_contact();
  contact.point.x() = nan;
  expect_invalid_argument_naming([&] { build_local_model(hemisphere(), contact, material, settings); }, "ToolContact");
  contact = pole_contact();
  contact.direction.z() = nan;
  expect_invalid_argument_naming([&] { build_local_model(hemisphere(), contact, material, settings); }, "ToolContact");

  const LocalModel model = build_local_model(hemisphere(), pole_contact(), material, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  const LocalSolution solution = solve_local_model(model, Eigen::Vector3d(0.0, nan, -1e-4));
  EXPECT_NE(solution.status, "ok");
  EXPECT_TRUE(all_finite(solution.forces));
  EXPECT_TRUE(solution.parameters.allFinite());
}

TEST(LocalModelDegenerate, InvalidSettingsAreNamed) {
  const geometry::Material material;
  const auto expect_named = [&](const LocalModelSettings& settings, const std::string& field) {
    SCOPED_TRACE(field);
    expect_invalid_argument_naming([&] { settings.validate(); }, field);
    expect_invalid_argument_naming([&] { build_local_model(hemisphere(), pole_contact(), material, settings); },
                                   field);
  };
  LocalModelSettings s = small_settings();
  s.sprinkling.node_count = 5;
  expect_named(s, "node_count");
  s = small_settings();
  s.sprinkling.radius_factor = 0.5;
  expect_named(s, "radius_factor");
  s = small_settings();
  s.sprinkling.oversampling = 0.5;
  expect_named(s, "oversampling");
  s = paper_settings();
  s.sprinkling.oversampling = 3;
  expect_named(s, "oversampling");
  s = small_settings();
  s.force.haptic_method = ForceMethod::energy;
  expect_named(s, "haptic_method");
  // The weak form always clamps the cut: a traction-free cut is refused, not ignored.
  s = small_settings();
  s.formulation = Formulation::galerkin;
  s.force.haptic_method = ForceMethod::reaction;
  s.sprinkling.outer = OuterCondition::traction_free;
  expect_named(s, "outer");
  for (const double coarse : {-1.0, std::nan(""), 1e4}) {
    s = LocalModelSettings{};
    s.enriched.volume_coarse_within_tool_radii = coarse;
    expect_named(s, "volume_coarse_within_tool_radii");
  }
  // The defaults and the paper's setup are valid.
  EXPECT_NO_THROW(LocalModelSettings{}.validate());
  EXPECT_NO_THROW(paper_settings().validate());
}

// ---------------------------------------------------------------------------------------------
// B. K_t is the condensation of the collocation system: F = K_t U_tool exactly, for any U_tool.

TEST(LocalModel, ToolStiffnessIsTheCondensation) {
  LocalModelSettings settings = small_settings();
  settings.force.haptic_method = ForceMethod::traction_integral;  // K_t through the traction map
  settings.sprinkling.oversampling = 1;  // square: K p = f holds row by row
  const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  const Eigen::Index n = static_cast<Eigen::Index>(model.cloud.size());
  EXPECT_NEAR(static_cast<double>(n), 60.0, 15.0);
  ASSERT_EQ(model.system.stiffness.rows(), 3 * n) << "square collocation";
  ASSERT_EQ(model.traction_map.cols(), 3 * n);
  EXPECT_TRUE(model.load_force_N.isZero(0.0)) << "no body force, no prescribed traction: no load";

  // An independent solve of the whole system K U = f₀ + G U_tool (dense LU, not the model's
  // sparse LU and not its stored unit responses).
  CollocationSolver dense(SolverSettings{SolverKind::dense_lu});
  ASSERT_TRUE(dense.factorize(model.system.stiffness).ok);

  std::mt19937 random(11);
  std::uniform_real_distribution<double> component(-1e-4, 1e-4);
  for (int trial = 0; trial < 3; ++trial) {
    const Eigen::Vector3d u_tool(component(random), component(random), component(random));
    SCOPED_TRACE(::testing::Message() << "U_tool = " << u_tool.transpose());
    const LocalSolution solution = solve_local_model(model, u_tool);
    ASSERT_EQ(solution.status, "ok");
    const Eigen::Vector3d kt_u = model.tool_stiffness_N_per_m * u_tool;
    const double scale = kt_u.norm();
    ASSERT_GT(scale, 0);

    // The returned parameters solve the collocation system.
    const Eigen::VectorXd f = model.system.constant_rhs + model.system.tool_rhs * u_tool;
    EXPECT_LT((model.system.stiffness * solution.parameters - f).norm(), 1e-10 * f.norm());
    // K_t U_tool = traction map · parameters, by the model's parameters and by the direct solve.
    EXPECT_LT((kt_u - model.traction_map * solution.parameters).norm(), 1e-10 * scale);
    EXPECT_LT((kt_u - solution.forces.traction_integral_N).norm(), 1e-10 * scale);
    EXPECT_LT((kt_u - solution.forces.haptic_N).norm(), 1e-10 * scale);
    Eigen::MatrixXd direct;
    ASSERT_TRUE(dense.solve(f, direct).ok);
    EXPECT_LT((kt_u - model.traction_map * direct.col(0)).norm(), 1e-10 * scale);

    // Linear: twice the displacement, twice every force.
    const LocalSolution twice = solve_local_model(model, 2 * u_tool);
    ASSERT_EQ(twice.status, "ok");
    const auto expect_doubled = [](const Eigen::Vector3d& once, const Eigen::Vector3d& doubled, const char* what) {
      EXPECT_LE((doubled - 2 * once).norm(), 1e-12 * doubled.norm()) << what;
    };
    expect_doubled(solution.forces.traction_integral_N, twice.forces.traction_integral_N, "traction");
    expect_doubled(solution.forces.reaction_N, twice.forces.reaction_N, "reaction");
    expect_doubled(solution.forces.paper_partition_N, twice.forces.paper_partition_N, "paper");
    expect_doubled(solution.forces.haptic_N, twice.forces.haptic_N, "haptic");
  }
  // Pushing into the tissue takes positive work, d·K_t d > 0, but square point collocation does
  // not guarantee it (the sign changes with the cloud and the surface mesh): printed, not
  // asserted. The least-squares default is asserted below.
  const Eigen::Vector3d d = pole_contact().direction;
  std::printf("  N = %d, K_t d.d = %.4e N/m, K_t =\n", static_cast<int>(n), d.dot(model.tool_stiffness_N_per_m * d));
  for (int r = 0; r < 3; ++r)
    std::printf("    %12.4e %12.4e %12.4e\n", model.tool_stiffness_N_per_m(r, 0), model.tool_stiffness_N_per_m(r, 1),
                model.tool_stiffness_N_per_m(r, 2));
}

// With the default least-squares collocation the sign of the tool stiffness is stable as the
// cloud changes (square collocation flips it: README, "Measured (MFS)").
TEST(LocalModel, LeastSquaresToolStiffnessIsPositive) {
  for (const int n : {34, 60, 100}) {
    LocalModelSettings settings = small_settings();
    settings.sprinkling.node_count = n;
    settings.force.reaction = false;
    const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
    ASSERT_TRUE(model.ok()) << model.status;
    const Eigen::Vector3d d = pole_contact().direction;
    const double stiffness = d.dot(model.tool_stiffness_N_per_m * d);
    std::printf("  N = %zu (+%zu points): K_t d.d = %.4e N/m\n", model.cloud.size(), model.cloud.extra_points.size(), stiffness);
    EXPECT_GT(stiffness, 0) << "N = " << n;
  }
}

// ---------------------------------------------------------------------------------------------
// C. Paper mode (B4, paper eqs. 7–9).

TEST(LocalModel, PaperModeSolvesEquation7) {
  const LocalModelSettings settings = paper_settings();
  const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  const int n = static_cast<int>(model.cloud.size());
  std::printf("  paper mode: N = %d nodes\n", n);
  EXPECT_NEAR(n, 34, 4);
  int patch_nodes = 0;
  for (const NodeKind kind : model.cloud.kinds) patch_nodes += kind == NodeKind::tool_patch;
  EXPECT_EQ(patch_nodes, 1);
  EXPECT_EQ(model.cloud.kinds[0], NodeKind::tool_patch);
  EXPECT_EQ(model.tip_node, 0);
  ASSERT_EQ(model.system.stiffness.rows(), 3 * n) << "square collocation";

  const Eigen::Vector3d u_tool(2e-5, -3e-5, -1e-4);
  const LocalSolution solution = solve_local_model(model, u_tool);
  ASSERT_EQ(solution.status, "ok");
  const Eigen::VectorXd& p = solution.parameters;
  // Eqs. 7–8: U_a = U_tool exactly; K_ba U_a + K_bb U_b = 0 (the right-hand side is zero here).
  EXPECT_EQ(p.segment<3>(0), u_tool);
  EXPECT_TRUE(model.system.constant_rhs.isZero(0.0));
  EXPECT_TRUE(model.system.tool_rhs.isZero(0.0)) << "paper mode: the tool enters through U_a, not the right-hand side";
  const Eigen::VectorXd residual = model.system.stiffness * p;
  Eigen::VectorXd p_a = Eigen::VectorXd::Zero(3 * n);
  p_a.segment<3>(0) = u_tool;
  const Eigen::VectorXd k_ba_u_a = model.system.stiffness * p_a;  // the tip's columns alone
  const double scale = k_ba_u_a.tail(3 * n - 3).norm();
  ASSERT_GT(scale, 0);
  EXPECT_LT(residual.tail(3 * n - 3).norm(), 1e-10 * scale);

  // Eq. 9: the tip's own rows (unscaled: traction [Pa]) applied to U are the tip residual, and
  // times the tributary area the paper's force.
  const ToolForces& f = solution.forces;
  Eigen::Vector3d tip_rows;
  for (int r = 0; r < 3; ++r) tip_rows[r] = residual[r] / model.system.row_scale[r];
  EXPECT_LT((f.paper_tip_residual_Pa - tip_rows).norm(), 1e-12 * tip_rows.norm());
  EXPECT_GT(model.tip_tributary_area_m2, 0);
  EXPECT_LT((f.paper_tip_residual_Pa * model.tip_tributary_area_m2 - f.paper_partition_N).norm(),
            1e-14 * f.paper_partition_N.norm());
  EXPECT_LT((f.haptic_N - f.paper_partition_N).norm(), 1e-10 * f.paper_partition_N.norm())
      << "paper_settings() feel the paper's force";
  std::printf("  paper mode: tip residual %s Pa, tributary area %.4e m^2, force %s N (traction integral %s N)\n",
              ::testing::PrintToString(f.paper_tip_residual_Pa.transpose().eval()).c_str(),
              model.tip_tributary_area_m2, ::testing::PrintToString(f.paper_partition_N.transpose().eval()).c_str(),
              ::testing::PrintToString(f.traction_integral_N.transpose().eval()).c_str());
}

// ---------------------------------------------------------------------------------------------
// D. Least-squares collocation.

TEST(LocalModel, LeastSquaresCollocationReportsItsMisfit) {
  LocalModelSettings settings = small_settings();
  settings.sprinkling.oversampling = 3;
  const LocalModel model = build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  const Eigen::Index n = static_cast<Eigen::Index>(model.cloud.size());
  const auto& k = model.system.stiffness;
  std::printf("  least squares: %d nodes, %d extra points, K %d x %d\n", static_cast<int>(n),
              static_cast<int>(model.cloud.extra_points.size()), static_cast<int>(k.rows()), static_cast<int>(k.cols()));
  EXPECT_GT(model.cloud.extra_points.size(), 0u);
  EXPECT_EQ(k.rows(), 3 * (n + static_cast<Eigen::Index>(model.cloud.extra_points.size())));
  ASSERT_GT(k.rows(), k.cols());

  const Eigen::Vector3d u_tool(0.0, 0.0, -1e-4);
  const Eigen::VectorXd f = model.system.constant_rhs + model.system.tool_rhs * u_tool;
  CollocationSolver solver(settings.solver);
  ASSERT_TRUE(solver.factorize(k).ok);
  Eigen::MatrixXd x;
  const SolveReport report = solver.solve(f, x);
  ASSERT_TRUE(report.ok) << report.failure;
  std::printf("  least squares: misfit %.3e, normal-equation residual %.3e\n", report.least_squares_residual,
              report.relative_residual);
  EXPECT_TRUE(std::isfinite(report.least_squares_residual));
  EXPECT_GT(report.least_squares_residual, 0);
  EXPECT_LT(report.relative_residual, 1e-8);
  // Both numbers, recomputed here.
  const Eigen::VectorXd misfit = k * x.col(0) - f;
  EXPECT_NEAR(report.least_squares_residual, misfit.norm() / f.norm(), 1e-9 * report.least_squares_residual);
  const Eigen::VectorXd k_t_f = k.transpose() * f;
  EXPECT_LT((k.transpose() * misfit).norm(), 1e-8 * k_t_f.norm());
  // The model's own response to U_tool is that least-squares solution.
  const LocalSolution solution = solve_local_model(model, u_tool);
  ASSERT_EQ(solution.status, "ok");
  EXPECT_LT((solution.parameters - x.col(0)).norm(), 1e-8 * x.norm());
}

}  // namespace
}  // namespace touchstone::realtime::mfs
