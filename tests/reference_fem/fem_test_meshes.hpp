#pragma once
// Small gmsh meshes for the reference FEM tests, generated once per process into the test's
// working folder.
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"

#include <gtest/gtest.h>

#include <string>
#include <utility>

namespace touchstone::fem::testing {

/// ctest runs the tests of one executable in parallel processes in one folder: a mesh file
/// named after the running test is private to it, and the same on every MPI rank.
inline std::string private_path(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string test = info ? std::string(info->test_suite_name()) + "." + info->name() : "global";
  for (char& c : test)
    if (c == '/') c = '_';
  return name + "-" + test + ".msh";
}

/// Meshes `parameters` into the test's private path: rank 0 writes, every rank waits for the file
/// (ranks writing one file at once leave it incomplete).
inline std::string mesh_on_rank_zero(const meshes::MeshParameters& parameters, const std::string& name) {
  const std::string path = private_path(name);
  if (MpiSession::rank() == 0) meshes::generate_mesh(parameters, path);
  MpiSession::barrier();
  return path;
}

/// Unit cube [0,1]³ with element size h, faces x_min … z_max. Rank 0 writes, all ranks wait.
inline std::string unit_cube_mesh(double h, const std::string& name) {
  meshes::MeshParameters parameters;
  parameters.benchmark = meshes::Benchmark::Box;
  parameters.box_size_m = {{1.0, 1.0, 1.0}};
  parameters.edge_size_m = h;
  parameters.max_size_m = h;
  return mesh_on_rank_zero(parameters, name);
}

/// The patch-test field u = G x + c [m], with a full (non-symmetric) G and tr G ≠ 0.
inline Eigen::Matrix3d affine_gradient() {
  Eigen::Matrix3d g;
  g << 1.0e-3, 2.0e-4, -3.0e-4, 5.0e-4, -2.0e-3, 1.0e-4, -4.0e-4, 3.0e-4, 1.5e-3;
  return g;
}
inline Eigen::Vector3d affine_field(const Eigen::Vector3d& x) {
  return affine_gradient() * x + Eigen::Vector3d(1.0e-4, -2.0e-4, 3.0e-4);
}

/// The affine field on the unit cube (h = 0.34) with four interior probes: prescribed on every
/// face, or (traction_faces) on x_min, y_min, z_min with its traction σ·n = (λ tr ε I + 2μ ε)·n
/// on the three others.
inline ElasticityProblem affine_patch_problem(const geometry::Material& material, bool traction_faces, const std::string& mesh_name) {
  ElasticityProblem problem;
  problem.mesh_path = unit_cube_mesh(0.34, mesh_name);
  problem.material = material;
  problem.clamped_boundaries.clear();
  for (const char* face : {"x_min", "y_min", "z_min"})
    problem.conditions.push_back({face, BoundaryCondition::Kind::displacement, affine_field});
  const Eigen::Matrix3d strain = 0.5 * (affine_gradient() + affine_gradient().transpose());
  const Eigen::Matrix3d stress = material.lame_lambda_Pa() * strain.trace() * Eigen::Matrix3d::Identity() +
                                 2 * material.shear_modulus_Pa() * strain;
  for (const auto& [face, normal] : {std::pair{"x_max", Eigen::Vector3d::UnitX()}, std::pair{"y_max", Eigen::Vector3d::UnitY()},
                                     std::pair{"z_max", Eigen::Vector3d::UnitZ()}}) {
    if (traction_faces)
      problem.conditions.push_back({face, BoundaryCondition::Kind::traction,
                                    [t = Eigen::Vector3d(stress * normal)](const Eigen::Vector3d&) { return t; }});
    else
      problem.conditions.push_back({face, BoundaryCondition::Kind::displacement, affine_field});
  }
  problem.probes = {{0.5, 0.5, 0.5}, {0.13, 0.71, 0.37}, {0.9, 0.2, 0.6}, {0.31, 0.33, 0.95}};
  problem.exact_displacement = affine_field;
  return problem;
}

/// The unit-cube manufactured-solution problem: `field` (u(x), traction(x, n), body_force(x))
/// prescribed as displacement on x_min, y_min, z_min, y_max and as traction on x_max, z_max,
/// with its body force and exact displacement (for the L2 error).
template <class Field>
ElasticityProblem manufactured_cube_problem(const Field& field, const geometry::Material& material, double h,
                                            const std::string& mesh_name) {
  ElasticityProblem problem;
  problem.mesh_path = unit_cube_mesh(h, mesh_name);
  problem.material = material;
  problem.clamped_boundaries.clear();
  for (const auto& face : {"x_min", "y_min", "z_min", "y_max"})
    problem.conditions.push_back({face, BoundaryCondition::Kind::displacement, [field](const Eigen::Vector3d& x) { return field.u(x); }});
  problem.conditions.push_back({"x_max", BoundaryCondition::Kind::traction, [field](const Eigen::Vector3d& x) { return field.traction(x, {1, 0, 0}); }});
  problem.conditions.push_back({"z_max", BoundaryCondition::Kind::traction, [field](const Eigen::Vector3d& x) { return field.traction(x, {0, 0, 1}); }});
  problem.body_force = [field](const Eigen::Vector3d& x) { return field.body_force(x); };
  problem.exact_displacement = [field](const Eigen::Vector3d& x) { return field.u(x); };
  return problem;
}

/// A coarse B2 hemisphere (R = 50 mm, a = 5 mm) for punch tests.
inline std::string coarse_hemisphere_mesh(const std::string& name) {
  meshes::MeshParameters parameters;
  parameters.benchmark = meshes::Benchmark::B2;
  parameters.body_radius_m = 0.05;
  parameters.tool_radius_m = 0.005;
  parameters.edge_size_m = 0.0025;
  parameters.size_growth = 0.5;
  parameters.max_size_m = 0.02;
  return mesh_on_rank_zero(parameters, name);
}

/// The B2 mesh of fem_benchmark's level 0 (R = 50 mm, a = 2.5 mm, edge a/4 at the patch rim):
/// the paper's Table 2 size, 12,642 P2 dofs.
inline std::string paper_size_b2_mesh(const std::string& name) {
  meshes::MeshParameters parameters;
  parameters.benchmark = meshes::Benchmark::B2;
  parameters.body_radius_m = 0.05;
  parameters.tool_radius_m = 0.0025;
  parameters.edge_size_m = 0.0025 / 4;
  parameters.size_growth = 0.5;
  parameters.max_size_m = 0.01;
  return mesh_on_rank_zero(parameters, name);
}

/// The level-0 mesh of studies/configs/b3_reference.toml's first family: B3 (R = 50 mm, a = 2.5 mm,
/// L = 5a = 12.5 mm), edge size a/16 graded as d^(3/4), max 2 mm. About 24k P2 dofs.
inline std::string b3_ladder_level0_mesh(const std::string& name) {
  meshes::MeshParameters parameters;
  parameters.benchmark = meshes::Benchmark::B3;
  parameters.body_radius_m = 0.05;
  parameters.tool_radius_m = 0.0025;
  parameters.local_radius_m = 0.0125;
  parameters.edge_size_m = 0.15625e-3;
  parameters.size_growth = 0.5;
  parameters.size_exponent = 0.75;
  parameters.max_size_m = 0.002;
  return mesh_on_rank_zero(parameters, name);
}

}  // namespace touchstone::fem::testing
