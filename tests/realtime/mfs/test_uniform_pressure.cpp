// Traction rows must carry a load: the deflection under a uniform pressure p on a disk of radius
// a on the flat face of a large body: the half-space answer is w(0) = 2(1−ν²) p a / E at the
// centre and w̄ = 16(1−ν²) p a / (3πE) on average over the disk (Johnson, Contact Mechanics
// §3.4). The local domain is the body ∩ ball(centre, L = 10a); the cut surface carries the
// Boussinesq point-load field of the total force P = π a² p, which differs from the disk
// load's field by O((a/L)²) there, so the local problem is the half-space problem.
//
// A second, smooth check: the Boussinesq field of a point force a above the surface is an exact
// solution of the Navier equations in the body; its tractions on the face and its values on the
// cut are the data, and the centre deflection is compared.
//
// Built twice. test_uniform_pressure: point collocation's traction rows, which miss the target;
// the tests pin their measured errors (a regression check, not the target).
// test_uniform_pressure_galerkin (label large, slow): the Galerkin formulation, which meets it.
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/realtime/mfs/collocation.hpp"
#include "touchstone/realtime/mfs/galerkin.hpp"
#include "touchstone/realtime/mfs/linear_solvers.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr double box_m = 0.1, a_m = 0.0025, pressure_Pa = 100.0;

const geometry::TriangleSurface& box() {
  static const geometry::TriangleSurface surface = [] {
    meshes::MeshParameters g;
    g.benchmark = meshes::Benchmark::Box;
    g.box_size_m = {box_m, box_m, box_m};
    g.edge_size_m = 0.01;
    const std::string path = "uniform_pressure_box_" + std::to_string(getpid()) + ".msh";
    meshes::generate_mesh(g, path);
    return meshes::load_msh_surface(path);
  }();
  return surface;
}

/// Boussinesq: point force P into a half-space z' ≥ 0 (depth z' = top − z), at the origin x₀.
Eigen::Vector3d boussinesq(const geometry::Material& m, double force_N, const Eigen::Vector3d& origin, const Eigen::Vector3d& x) {
  const Eigen::Vector3d d = x - origin;
  const double depth = -d.z(), rho = d.norm();
  const double c = force_N * (1 + m.poisson_ratio) / (2 * pi * m.youngs_modulus_Pa);
  const double radial = c * (depth / (rho * rho * rho) - (1 - 2 * m.poisson_ratio) / (rho * (rho + depth)));
  const double down = c * (depth * depth / (rho * rho * rho) + 2 * (1 - m.poisson_ratio) / rho);
  return {radial * d.x(), radial * d.y(), -down};
}

/// σ(u) n of the Boussinesq field [Pa], its gradient by central differences.
Eigen::Vector3d boussinesq_traction(const geometry::Material& m, double force_N, const Eigen::Vector3d& origin,
                                    const Eigen::Vector3d& x, const Eigen::Vector3d& n) {
  const double h = 1e-6;  // [m]: the field varies on the scale a = 2.5 mm
  Eigen::Matrix3d g;
  for (int k = 0; k < 3; ++k)
    g.col(k) = (boussinesq(m, force_N, origin, x + h * Eigen::Vector3d::Unit(k)) -
                boussinesq(m, force_N, origin, x - h * Eigen::Vector3d::Unit(k))) / (2 * h);
  const Eigen::Matrix3d e = 0.5 * (g + g.transpose());
  return (m.lame_lambda_Pa() * e.trace() * Eigen::Matrix3d::Identity() + 2 * m.shear_modulus_Pa() * e) * n;
}

/// The disk at the centre of the box's top face.
ToolContact disk_contact() {
  ToolContact contact;
  contact.point = {0.5 * box_m, 0.5 * box_m, box_m};
  contact.radius_m = a_m;
  return contact;
}

/// The local domain box ∩ ball(centre, L = 10a) sprinkled with N nodes.
NodeCloud sprinkle_box(int node_count, double oversampling) {
  SprinklingSettings settings;
  settings.node_count = node_count;
  settings.local_radius_m = 10 * a_m;
  settings.oversampling = oversampling;
  settings.radius_factor = 3.0;
  settings.boundary_radius_factor = 3.6;
  return sprinkle_nodes(box(), disk_contact(), settings);
}

struct Deflection {
  double centre_m = 0, mean_m = 0;
};

/// The downward deflection of u_h (positive) at the disk's centre and averaged over the disk.
Deflection measure_deflection(const NodeCloud& cloud, const Eigen::VectorXd& parameters, const MlsSettings& mls) {
  const ToolContact contact = disk_contact();
  Deflection w;
  MlsEvaluation scratch;
  Eigen::Vector3d u;
  EXPECT_EQ(evaluate_displacement(cloud, parameters, contact.point, mls, scratch, u), MlsStatus::ok);
  w.centre_m = -u.z();
  const PatchQuadrature disk = patch_quadrature(box(), contact, 16, 32);
  double area = 0;
  for (std::size_t q = 0; q < disk.points.size(); ++q) {
    EXPECT_EQ(evaluate_displacement(cloud, parameters, disk.points[q], mls, scratch, u), MlsStatus::ok);
    w.mean_m -= disk.weights[q] * u.z();
    area += disk.weights[q];
  }
  w.mean_m /= area;
  return w;
}

/// Rows: pressure on the patch (half on the edge ring), traction-free elsewhere on the face,
/// Boussinesq on the cut; solves and returns the downward deflection (positive).
enum class Load { uniform_disk, point_force_above };

// Each build of this file (collocation, Galerkin) uses one of the two solvers below.
[[maybe_unused]] Deflection solve(const geometry::Material& m, int node_count, double oversampling, Load load_case) {
  const ToolContact contact = disk_contact();
  NodeCloud cloud = sprinkle_box(node_count, oversampling);
  const double force_N = pi * a_m * a_m * pressure_Pa;
  const auto load = [&](NodeKind kind, const Eigen::Vector3d& x, const Eigen::Vector3d& n,
                        std::array<CollocationRow, 3>& rows) {
    if (load_case == Load::point_force_above) {  // exact smooth solution: Boussinesq from a point a above the surface
      const Eigen::Vector3d origin = contact.point + Eigen::Vector3d(0, 0, a_m);
      const auto field = [&](const Eigen::Vector3d& y) { return boussinesq(m, force_N, origin, y); };
      const Eigen::Vector3d t = boussinesq_traction(m, force_N, origin, x, n);
      for (int k = 0; k < 3; ++k) {
        rows[k].direction = Eigen::Vector3d::Unit(k);
        rows[k].tool.setZero();
        if (kind == NodeKind::cut) { rows[k].type = CollocationRow::Type::dirichlet; rows[k].value = field(x)[k]; }
        else if (kind != NodeKind::interior) { rows[k].type = CollocationRow::Type::traction; rows[k].value = t[k]; }
      }
      return;
    }
    if (kind != NodeKind::tool_patch && kind != NodeKind::cut) return;
    const double r = (x - contact.point).norm();
    const double on_edge = std::abs(r - a_m) < 1e-3 * a_m ? 0.5 : 1.0;
    for (int k = 0; k < 3; ++k) {
      rows[k].direction = Eigen::Vector3d::Unit(k);
      rows[k].tool.setZero();
      if (kind == NodeKind::tool_patch) {
        rows[k].type = CollocationRow::Type::traction;
        rows[k].value = -on_edge * pressure_Pa * n[k];
      } else {
        rows[k].type = CollocationRow::Type::dirichlet;
        rows[k].value = boussinesq(m, force_N, contact.point, x)[k];
      }
    }
  };
  for (std::size_t j = 0; j < cloud.size(); ++j) load(cloud.kinds[j], cloud.positions[j], cloud.normals[j], cloud.rows[j]);
  for (CollocationPoint& p : cloud.extra_points) load(p.kind, p.position, p.normal, p.rows);

  CollocationSettings collocation;
  collocation.mls.max_support_scale = 1.5;
  CollocationSystem system;
  assemble_collocation(cloud, m, collocation, system);
  EXPECT_TRUE(system.status.ok()) << "point " << system.status.node;
  CollocationSolver solver;
  EXPECT_TRUE(solver.factorize(system.stiffness).ok);
  Eigen::MatrixXd parameters;
  EXPECT_TRUE(solver.solve(system.constant_rhs, parameters).ok);

  return measure_deflection(cloud, parameters.col(0), collocation.mls);
}

/// The same problems in the weak form (galerkin.hpp): the pressure is the load ∫ h_J t̄ dA on
/// the disk, traction-free is natural, the cut's Boussinesq values are imposed like the cut's
/// u = 0 of the punch (Nitsche or penalty).
[[maybe_unused]] Deflection solve_galerkin(const geometry::Material& m, int node_count, Load load_case, Constraint constraint) {
  const ToolContact contact = disk_contact();
  const NodeCloud cloud = sprinkle_box(node_count, 1);
  const double force_N = pi * a_m * a_m * pressure_Pa;
  const Eigen::Vector3d origin = contact.point + Eigen::Vector3d(0, 0, load_case == Load::point_force_above ? a_m : 0.0);
  const auto field = [&](const Eigen::Vector3d& y) { return boussinesq(m, force_N, origin, y); };

  GalerkinSettings galerkin;
  galerkin.constraint = constraint;
  const double length = 10 * a_m;
  const PatchQuadrature volume = volume_quadrature(box(), contact, length);
  const PatchQuadrature cut = cut_quadrature(box(), contact, length, 24, 48);
  // No tool: an empty patch quadrature leaves the patch to the load.
  const GalerkinSystem system = assemble_galerkin(cloud, m, contact, volume, PatchQuadrature{}, cut, galerkin);
  EXPECT_EQ(system.status, MlsStatus::ok) << "quadrature point " << system.failed_point;

  // Loads: the disk pressure, or the smooth field's traction on the whole face ∩ ball(L).
  ToolContact face = contact;
  if (load_case == Load::point_force_above) face.radius_m = 0.999 * length;
  const PatchQuadrature loaded = patch_quadrature(box(), face, 32, 64);
  std::vector<Eigen::Vector3d> traction(loaded.points.size());
  for (std::size_t q = 0; q < loaded.points.size(); ++q) {
    if (load_case == Load::uniform_disk) {
      traction[q] = -pressure_Pa * loaded.normals[q];
      continue;
    }
    traction[q] = boussinesq_traction(m, force_N, origin, loaded.points[q], loaded.normals[q]);
  }
  std::vector<Eigen::Vector3d> cut_values(cut.points.size());
  for (std::size_t q = 0; q < cut.points.size(); ++q) cut_values[q] = field(cut.points[q]);
  Eigen::VectorXd pressure_load, cut_load;
  EXPECT_TRUE(traction_load(cloud, loaded, traction, galerkin, pressure_load));
  EXPECT_TRUE(prescribed_displacement_load(cloud, m, cut, cut_values, galerkin, cut_load));
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(system.stiffness);
  EXPECT_TRUE(ldlt.info() == Eigen::Success && ldlt.isPositive()) << "K is not positive definite";
  const Eigen::VectorXd parameters = ldlt.solve(pressure_load + cut_load);

  return measure_deflection(cloud, parameters, galerkin.mls);
}

#ifdef TOUCHSTONE_GALERKIN_TESTS
// The weak form's traction boundary condition. Measured (penalty; volume quadrature graded like
// the cloud, 32 × 24 × 32 points): centre +0.5 %, +4.2 %, +0.5 % and mean −5.8 %, −2.8 %,
// −1.3 % at N = 200, 400, 800. Points uniform in ρ under-integrate K and leave spurious soft
// modes (erratic deflections), hence the grading.
TEST(UniformPressureGalerkin, DiskDeflectionMatchesTheHalfSpace) {
  const geometry::Material m{10.0e3, 0.45};
  const double centre = 2 * (1 - m.poisson_ratio * m.poisson_ratio) * pressure_Pa * a_m / m.youngs_modulus_Pa;
  const double mean = 16 * (1 - m.poisson_ratio * m.poisson_ratio) * pressure_Pa * a_m / (3 * pi * m.youngs_modulus_Pa);
  for (const Constraint constraint : {Constraint::penalty})
    for (const int n : {200, 400, 800}) {
      const Deflection w = solve_galerkin(m, n, Load::uniform_disk, constraint);
      std::printf("  %s N = %d: centre %.4e m (%+.2f %%), mean %.4e m (%+.2f %%)\n", to_string(constraint).c_str(), n,
                  w.centre_m, 100 * (w.centre_m / centre - 1), w.mean_m, 100 * (w.mean_m / mean - 1));
      if (n == 800) {
        EXPECT_NEAR(w.centre_m / centre, 1.0, 0.05) << to_string(constraint) << ", centre deflection, N = " << n;
        EXPECT_NEAR(w.mean_m / mean, 1.0, 0.05) << to_string(constraint) << ", mean deflection, N = " << n;
      }
    }
}

// Measured: −8.1 %, −0.4 %, +0.3 % at N = 200, 400, 800, Nitsche and penalty alike.
TEST(UniformPressureGalerkin, SmoothPointForceFieldIsReproduced) {
  const geometry::Material m{10.0e3, 0.45};
  const Eigen::Vector3d top(0.5 * box_m, 0.5 * box_m, box_m);
  const double centre = -boussinesq(m, pi * a_m * a_m * pressure_Pa, top + Eigen::Vector3d(0, 0, a_m), top).z();
  for (const Constraint constraint : {Constraint::nitsche, Constraint::penalty})
    for (const int n : {200, 400, 800}) {
      const Deflection w = solve_galerkin(m, n, Load::point_force_above, constraint);
      std::printf("  %s N = %d: centre %.4e m (%+.2f %%)\n", to_string(constraint).c_str(), n, w.centre_m, 100 * (w.centre_m / centre - 1));
      if (n == 800) {
        EXPECT_NEAR(w.centre_m / centre, 1.0, 0.02) << to_string(constraint) << ", N = " << n;
      }
    }
}
#else

// Point collocation's traction rows do not carry the load: the half-space target (±5 %, which
// the Galerkin build meets) is missed by far, and not monotonically in N (measured, oversampling
// 3: centre −72 %, −73 %, −43 % and mean −70 %, −76 %, −45 % at N = 200, 400, 800). These tests
// pin today's errors at N = 800 within ±3 percentage points, so that a change to the traction
// rows shows here, for better or worse; they are not the target.
TEST(UniformPressure, CollocationDiskDeflectionStaysAtItsMeasuredError) {
  const geometry::Material m{10.0e3, 0.45};
  const double centre = 2 * (1 - m.poisson_ratio * m.poisson_ratio) * pressure_Pa * a_m / m.youngs_modulus_Pa;
  const double mean = 16 * (1 - m.poisson_ratio * m.poisson_ratio) * pressure_Pa * a_m / (3 * pi * m.youngs_modulus_Pa);
  const Deflection w = solve(m, 800, 3.0, Load::uniform_disk);
  EXPECT_NEAR(w.centre_m / centre - 1, -0.4322, 0.03) << "centre deflection, N = 800";
  EXPECT_NEAR(w.mean_m / mean - 1, -0.4472, 0.03) << "mean deflection, N = 800";
}

// Measured (oversampling 3): −36 %, −30 %, −29 % at N = 200, 400, 800; pinned at N = 800.
TEST(UniformPressure, CollocationSmoothPointForceFieldStaysAtItsMeasuredError) {
  const geometry::Material m{10.0e3, 0.45};
  const Eigen::Vector3d top(0.5 * box_m, 0.5 * box_m, box_m);
  const double centre = -boussinesq(m, pi * a_m * a_m * pressure_Pa, top + Eigen::Vector3d(0, 0, a_m), top).z();
  const Deflection w = solve(m, 800, 3.0, Load::point_force_above);
  EXPECT_NEAR(w.centre_m / centre - 1, -0.2892, 0.03) << "N = 800";
}

#endif  // TOUCHSTONE_GALERKIN_TESTS

}  // namespace
}  // namespace touchstone::realtime::mfs
