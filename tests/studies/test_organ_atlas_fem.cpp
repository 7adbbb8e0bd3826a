// The organ atlas's FEM (studies/organ_atlas): the energy the solver reports under inhomogeneous
// Dirichlet data, the half-space closed form, and K_ext on a coarse hemisphere against it.
#include "touchstone/studies/organ_atlas.hpp"

#include "reference_fem/fem_test_meshes.hpp"
#include "touchstone/meshes/organ_geometry.hpp"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

namespace touchstone::studies {
namespace {

constexpr double a = 0.0025, l = 0.0125, body_radius_m = 0.05;

geometry::Material punch_material() {
  geometry::Material m;
  m.youngs_modulus_Pa = 10e3;
  m.poisson_ratio = 0.45;
  return m;
}

// energy_J = ½ uᵀ K u is summed cell by cell over the full (distributed) solution, so with a
// prescribed affine field on every face it is the exact energy ½ σ:ε |Ω| (P2 holds the field
// exactly), not the energy of the homogeneous part alone.
TEST(OrganAtlasEnergy, IsTheTrueEnergyUnderInhomogeneousDirichletData) {
  geometry::Material material;
  material.youngs_modulus_Pa = 10e3;
  material.poisson_ratio = 0.45;
  fem::ElasticityProblem problem = fem::testing::affine_patch_problem(material, false, "atlas_energy_cube");
  problem.exact_displacement = nullptr;
  problem.solver.solver = fem::LinearSolver::direct_mumps;
  const fem::ElasticitySolution s = fem::solve_elasticity(problem);
  const Eigen::Matrix3d g = fem::testing::affine_gradient();
  const Eigen::Matrix3d strain = 0.5 * (g + g.transpose());
  const Eigen::Matrix3d stress = material.lame_lambda_Pa() * strain.trace() * Eigen::Matrix3d::Identity() +
                                 2 * material.shear_modulus_Pa() * strain;
  const double exact = 0.5 * (stress.array() * strain.array()).sum();  // unit cube: |Ω| = 1 m³
  EXPECT_NEAR(s.energy_J, exact, 1e-8 * exact);
}

// The closed form −∮ ψ_m·σ(ψ_n) n dA over the hemisphere of radius L: converged in the quadrature
// (48 × 64 against 96 × 128 points to 1e-9), both tangential modes alike, no coupling between the
// modes (axisymmetry), and ∝ E. The normal entry lies below the punch's own half-space stiffness
// 4Ga/(1 − ν) (the exterior holds part of the energy only).
TEST(OrganAtlasHalfSpace, ClosedFormConvergesAndHasThePunchSymmetry) {
  const geometry::Material m = punch_material();
  const Eigen::Matrix3d k = half_space_exterior_stiffness_N_per_m(a, l, m, 48, 64);
  const Eigen::Matrix3d fine = half_space_exterior_stiffness_N_per_m(a, l, m, 96, 128);
  EXPECT_LT((k - fine).cwiseAbs().maxCoeff(), 1e-9 * k(0, 0));
  EXPECT_NEAR(k(1, 1), k(2, 2), 1e-9 * k(1, 1));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      if (i != j) {
        EXPECT_LT(std::abs(k(i, j)), 1e-9 * k(0, 0)) << i << ", " << j;
      }
    }
  const double punch = realtime::mfs::punch_half_space_stiffness_N_per_m(realtime::mfs::PunchMode::normal, a, m);
  EXPECT_GT(k(0, 0), 0.0);
  EXPECT_LT(k(0, 0), punch);
  EXPECT_GT(k(1, 1), 0.0);
  geometry::Material stiffer = m;
  stiffer.youngs_modulus_Pa *= 3;
  EXPECT_NEAR(half_space_exterior_stiffness_N_per_m(a, l, stiffer)(0, 0), 3 * k(0, 0), 1e-12 * k(0, 0));
}

// The shipped atlas studies read (every key known and valid); a misspelt key is an error naming
// the file and the key; angles take units.
TEST(OrganAtlasStudyFile, ShippedStudiesReadAndUnknownKeysAreNamed) {
  for (const char* name : {"atlas_hemisphere.toml", "atlas_b1.toml"}) {
    ConfigTable config = ConfigTable::from_file(std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/" + name);
    const OrganAtlasStudy study = read_organ_atlas_study(config);
    EXPECT_EQ(study.modes, AtlasModes::all) << name;
    EXPECT_TRUE(study.cut_translations) << name;
    EXPECT_EQ(study.refinements, (std::vector<int>{0, 1, 2})) << name;
    EXPECT_DOUBLE_EQ(study.geometry.tool_radius_m, a) << name;
    EXPECT_DOUBLE_EQ(study.geometry.local_radius_m, l) << name;
  }
  // The organ studies: a generated surface, the normal mode, the sampled region; a key of the
  // benchmark form (polar_angles) is unknown on an organ.
  for (const auto& [name, modes] : {std::pair<const char*, AtlasModes>{"atlas_stomach.toml", AtlasModes::all},
                                     std::pair<const char*, AtlasModes>{"atlas_organ_hemisphere.toml", AtlasModes::normal}}) {
    ConfigTable config = ConfigTable::from_file(std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/" + name);
    const OrganAtlasStudy study = read_organ_atlas_study(config);
    EXPECT_EQ(study.geometry.benchmark, meshes::Benchmark::Organ) << name;
    EXPECT_EQ(study.modes, modes) << name;
    EXPECT_EQ(study.cut_translations, modes == AtlasModes::all) << name;  // the cross-check compares K_nn only
    EXPECT_FALSE(study.generated_organ.empty()) << name;
    EXPECT_TRUE(std::isnan(study.region_centre_m[0])) << name;  // the organ's highest point
  }
  ConfigTable stomach = ConfigTable::from_file(std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/atlas_stomach.toml");
  EXPECT_DOUBLE_EQ(read_organ_atlas_study(stomach).region_radius_m, 0.02);
  ConfigTable angles_on_organ = ConfigTable::from_string(
      "[geometry]\nbenchmark = \"organ\"\ntool_radius = \"2.5 mm\"\n[material]\nyoungs_modulus = \"10 kPa\"\npoisson_ratio = 0.45\n"
      "[organ]\ngenerate = \"stomach\"\n[atlas]\npolar_angles = [\"10 deg\"]\n",
      "organ.toml");
  try {
    read_organ_atlas_study(angles_on_organ);
    FAIL() << "polar_angles was accepted on an organ";
  } catch (const ConfigError& error) {
    EXPECT_NE(std::string(error.what()).find("atlas.polar_angles"), std::string::npos) << error.what();
  }
  ConfigTable hemisphere = ConfigTable::from_file(std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/atlas_hemisphere.toml");
  EXPECT_NEAR(read_organ_atlas_study(hemisphere).polar_angles_rad.at(2), 30 * 3.14159265358979323846 / 180, 1e-15);
  // The problem's keys are required (a default would be a guess): named when missing.
  ConfigTable bare = ConfigTable::from_string("[atlas]\npolar_angles = [\"10 deg\"]\n", "bare.toml");
  try {
    read_organ_atlas_study(bare);
    FAIL() << "an atlas without the body, tool and material was accepted";
  } catch (const ConfigError& error) {
    EXPECT_NE(std::string(error.what()).find("missing key 'geometry.body_radius'"), std::string::npos) << error.what();
  }
  ConfigTable typo = ConfigTable::from_string(
      "[geometry]\nbody_radius = \"50 mm\"\ntool_radius = \"2.5 mm\"\n[material]\nyoungs_modulus = \"10 kPa\"\npoisson_ratio = 0.45\n"
      "[atlas]\npolar_angle = [\"10 deg\"]\n",
      "typo.toml");
  try {
    read_organ_atlas_study(typo);
    FAIL() << "an unknown key was accepted";
  } catch (const ConfigError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("typo.toml"), std::string::npos) << message;
    EXPECT_NE(message.find("atlas.polar_angle"), std::string::npos) << message;
  }
}

/// A work folder for one test's meshes and solutions, removed with its contents when the test
/// ends (each run left about 3 MB in the temporary folder).
class WorkDirectory {
 public:
  explicit WorkDirectory(const std::string& name)
      : root_(std::filesystem::path(::testing::TempDir()) / ("atlas_fem_" + std::to_string(::getpid()))), path_(root_ / name) {
    if (fem::MpiSession::rank() == 0) std::filesystem::create_directories(path_);
    fem::MpiSession::barrier();
  }
  ~WorkDirectory() {
    fem::MpiSession::barrier();
    std::error_code ignored;
    if (fem::MpiSession::rank() == 0) std::filesystem::remove_all(root_, ignored);
  }
  WorkDirectory(const WorkDirectory&) = delete;
  WorkDirectory& operator=(const WorkDirectory&) = delete;
  std::string path() const { return path_.string(); }

 private:
  std::filesystem::path root_, path_;
};

meshes::MeshParameters coarse_geometry(meshes::Benchmark benchmark, double body) {
  meshes::MeshParameters g;
  g.benchmark = benchmark;
  g.body_radius_m = body;
  g.tool_radius_m = a;
  g.local_radius_m = l;
  g.edge_size_m = 2 * a;  // on the cut sphere at level 0
  g.size_growth = 0.5;
  g.size_exponent = 1.0;
  g.max_size_m = body / 4;
  return g;
}

geometry::Material tissue() {
  geometry::Material material;
  material.youngs_modulus_Pa = 10e3;
  material.poisson_ratio = 0.45;
  return material;
}

AtlasRunOptions uncached() {
  AtlasRunOptions options;
  options.cache_directory.clear();
  return options;
}

// The FEM and the closed form describe the same thing: on the B1 cylinder the exterior stiffness
// tends to the half-space value as W grows (the clamped base's excess falls about as 5 L/W). At
// W = 160a the coarse two-level result lies within a few per cent above it.
TEST(OrganAtlasFem, WideCylinderApproachesTheHalfSpaceClosedForm) {
  const ExteriorStiffness k = exterior_stiffness_fem(coarse_geometry(meshes::Benchmark::B1, 160 * a), tissue(),
                                                     AtlasModes::normal, false, {0, 1}, 1e-4, fem::SolverParameters{},
                                                     uncached(), WorkDirectory("wide_b1").path());
  const double half_space = half_space_exterior_stiffness_N_per_m(a, l, punch_material())(0, 0);
  const double ratio = k.stiffness_N_per_m(0, 0) / half_space;
  std::printf("B1 W = 160a: K_ext normal %.6g N/m, half-space %.6g N/m, ratio %.5f\n", k.stiffness_N_per_m(0, 0),
              half_space, ratio);
  EXPECT_GT(ratio, 1.0);
  EXPECT_LT(ratio, 1.05);
}

// K_ext on the hemisphere R = 20a at the pole, normal mode, on three coarse levels (2a, a, a/2 on
// the cut): the level-to-level change shrinks at about second order, and the result is above the
// half-space closed form. Not by a few per cent: the exterior carries the whole effect of the
// finite body and its clamped base, which on the total punch stiffness is diluted by the energy
// of the local domain (B2: 1.04 × Sneddon); measured here 1.227 (levels 18.213, 17.861,
// 17.794 N/m, Richardson 17.779 N/m ± 0.09 %, half-space 14.490 N/m).
TEST(OrganAtlasFem, HemispherePoleIsStifferThanTheHalfSpaceAndConverges) {
  const ExteriorStiffness k = exterior_stiffness_fem(coarse_geometry(meshes::Benchmark::B2, body_radius_m), tissue(),
                                                     AtlasModes::normal, false, {0, 1, 2}, 1e-4, fem::SolverParameters{},
                                                     uncached(), WorkDirectory("pole").path());
  ASSERT_EQ(k.levels_N_per_m.size(), 3u);
  const double half_space = half_space_exterior_stiffness_N_per_m(a, l, punch_material())(0, 0);
  const double k0 = k.levels_N_per_m[0](0, 0), k1 = k.levels_N_per_m[1](0, 0), k2 = k.levels_N_per_m[2](0, 0);
  std::printf("K_ext normal per level: %.6g %.6g %.6g N/m (dofs %zu %zu %zu), extrapolated %.6g N/m, order %.3g, "
              "half-space %.6g N/m, ratio %.5f (finest %.5f)\n",
              k0, k1, k2, k.dofs[0], k.dofs[1], k.dofs[2], k.stiffness_N_per_m(0, 0), k.observed_order, half_space,
              k.stiffness_N_per_m(0, 0) / half_space, k2 / half_space);
  // (b) The discrete energy converges from above: each change at most a third of the previous one.
  EXPECT_GT(k0, k1);
  EXPECT_GT(k1, k2);
  EXPECT_LT(k1 - k2, (k0 - k1) / 3);
  EXPECT_TRUE(k.asymptotic);
  EXPECT_LT(k.relative_error, 0.005);
  // (a) Above the half-space: 1.227 measured, ± 0.01 for solver and meshing differences.
  const double ratio = k.stiffness_N_per_m(0, 0) / half_space;
  EXPECT_NEAR(ratio, 1.227, 0.01);
}

// The matrix comes from one solve per trace and the reaction's work against every other trace
// (fem::BoundaryWork). Its checks: reciprocity (K symmetric before it is symmetrised, to the
// solver's tolerance), the modes' block independent of whether the cut translations are added
// (the same solves), positive definite, and the diagonal equal to twice each solve's energy
// (checked inside exterior_stiffness_fem, which throws otherwise). A shift of the cut along the
// push loads the exterior the way the normal mode does, so their coupling is positive, and the
// rigid shift of the whole cut is stiffer than the punch mode, whose trace decays away from the
// axis (about 26× on this coarse mesh).
TEST(OrganAtlasFem, CutTranslationsAreReciprocalAndLeaveTheModesUnchanged) {
  const meshes::MeshParameters g = coarse_geometry(meshes::Benchmark::B2, body_radius_m);
  const ExteriorStiffness modes = exterior_stiffness_fem(g, tissue(), AtlasModes::all, false, {0}, 1e-4,
                                                         fem::SolverParameters{}, uncached(), WorkDirectory("modes").path());
  const ExteriorStiffness with = exterior_stiffness_fem(g, tissue(), AtlasModes::all, true, {0}, 1e-4,
                                                        fem::SolverParameters{}, uncached(), WorkDirectory("shift").path());
  const Eigen::MatrixXd k = with.stiffness_N_per_m.topLeftCorner(6, 6);
  std::printf("K_ext with the cut translations (N/m), asymmetry %.3g:\n", with.asymmetry);
  for (int i = 0; i < 6; ++i) std::printf("  %10.5g %10.5g %10.5g %10.5g %10.5g %10.5g\n", k(i, 0), k(i, 1), k(i, 2), k(i, 3), k(i, 4), k(i, 5));
  EXPECT_LT(with.asymmetry, 1e-6);
  EXPECT_LT(modes.asymmetry, 1e-6);
  EXPECT_LT((k.topLeftCorner(3, 3) - modes.stiffness_N_per_m.topLeftCorner(3, 3)).cwiseAbs().maxCoeff(), 1e-9 * k(0, 0));
  EXPECT_TRUE(modes.stiffness_N_per_m.bottomRightCorner(3, 3).isZero(0.0));
  EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(k).info(), Eigen::Success);
  EXPECT_GT(k(0, 3), 0.0);
  EXPECT_GT(k(3, 3), 10 * k(0, 0));
  // At the pole the body is symmetric about the axis: the normal mode does not couple with the
  // sideways shifts, nor the shift along the axis with them (to the unstructured mesh's asymmetry,
  // 7e-4 of the shift's stiffness here).
  EXPECT_LT(std::abs(k(0, 4)) + std::abs(k(0, 5)) + std::abs(k(3, 4)) + std::abs(k(3, 5)), 2e-3 * k(3, 3));
}

// The generic path: the hemisphere given as an STL surface (8,000 triangles; the base held by
// the plane rule z ≤ 0), remeshed by gmsh, the ball cut out along the exact sphere and closed by a
// triangulated cap (meshes/local_ball_cut). On the same two coarse levels as the dedicated B2
// exterior of the test above (18.213 and 17.861 N/m there) it gives the same K_ext at level 1
// within 0.1 % (level 0, where the faceted input and the exact sphere differ most, is only checked
// to lie above level 1; the README's atlas section gives the figures). The three-level comparison
// is `touchstone atlas studies/configs/atlas_organ_hemisphere.toml` against atlas_hemisphere.toml's
// pole sample.
TEST(OrganAtlasFem, HemisphereAsAnStlSurfaceGivesTheDedicatedExteriorStiffness) {
  const WorkDirectory work("organ_pole");
  const std::string directory = work.path();
  const std::string surface = directory + "/hemisphere.stl";
  if (fem::MpiSession::rank() == 0) {
    meshes::OrganParameters organ;
    organ.shape = meshes::OrganShape::hemisphere;
    organ.target_triangles = 8000;
    organ.hemisphere_radius_m = body_radius_m;
    meshes::write_organ_mesh(organ, surface);
  }
  fem::MpiSession::barrier();
  meshes::MeshParameters g = coarse_geometry(meshes::Benchmark::Organ, body_radius_m);
  g.organ.surface_path = surface;
  g.organ.contact_point_m = {0.0, 0.0, body_radius_m};
  g.organ.attachment.plane_normal = {0.0, 0.0, 1.0};
  const ExteriorStiffness k = exterior_stiffness_fem(g, tissue(), AtlasModes::normal, false, {0, 1}, 1e-4, fem::SolverParameters{},
                                                     uncached(), directory);
  ASSERT_EQ(k.levels_N_per_m.size(), 2u);
  const double k0 = k.levels_N_per_m[0](0, 0), k1 = k.levels_N_per_m[1](0, 0);
  std::printf("organ surface at the pole: K_ext normal per level %.6g %.6g N/m (dofs %zu %zu)\n", k0, k1, k.dofs[0], k.dofs[1]);
  EXPECT_GT(k0, k1);
  EXPECT_NEAR(k1, 17.861, 1e-3 * 17.861);
  // The punch frame sits on the rim circle found on the surface: below the pole by R − √(R² − a²).
  const realtime::mfs::PunchFrame frame = atlas_punch_frame(g);
  EXPECT_NEAR(frame.origin.z(), std::sqrt(body_radius_m * body_radius_m - a * a), 2e-5);
  EXPECT_NEAR(frame.axes.col(2).z(), -1.0, 2e-3);
}

}  // namespace
}  // namespace touchstone::studies
