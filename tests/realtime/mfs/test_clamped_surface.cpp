// Clamped surfaces (clamped_surface.hpp): the quadrature of the hemisphere's base inside the
// local ball has the area of the lens where the ball's trace on the base plane overlaps the
// base disk; a contact near the base (B5, polar angle 80°, L = 12.5 mm reaching z = 0) holds the
// base in the Galerkin model — stiffer than leaving it free, and the tool's force balanced by
// the reaction of the cut and the base together — while collocation refuses it with a status.
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/realtime/mfs/clamped_surface.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr double body_radius_m = 0.05, tool_radius_m = 0.0025, local_radius_m = 0.0125;

struct Hemisphere {
  geometry::TriangleSurface organ;
  ClampedSurface base;
};

const Hemisphere& hemisphere() {
  static const Hemisphere h = [] {
    meshes::MeshParameters g;
    g.benchmark = meshes::Benchmark::B2;
    g.edge_size_m = 0.0005;
    g.size_growth = 0.3;
    g.max_size_m = 0.003;
    const std::string path = "test_clamped_" + std::to_string(::getpid()) + ".msh";
    meshes::generate_mesh(g, path);
    meshes::SurfaceReadOptions base_only;
    base_only.msh_groups = {"base"};
    const meshes::SurfaceMesh base = meshes::read_surface_mesh(path, base_only);
    Hemisphere result{meshes::load_msh_surface(path), ClampedSurface{base.vertices, base.triangles}};
    std::remove(path.c_str());
    return result;
  }();
  return h;
}

/// The frictionless punch at polar angle θ in the x–z plane, pushed along the inward normal.
ToolContact contact_at(double polar_angle_rad) {
  const Eigen::Vector3d n(std::sin(polar_angle_rad), 0.0, std::cos(polar_angle_rad));
  ToolContact c;
  c.point = body_radius_m * n;
  c.direction = -n;
  c.radius_m = tool_radius_m;
  return c;
}

/// Area of the overlap of two disks of radii r and s whose centres are d apart.
double lens_area(double r, double s, double d) {
  if (d >= r + s) return 0;
  if (d <= std::abs(r - s)) return pi * std::min(r, s) * std::min(r, s);
  const double a = r * r * std::acos((d * d + r * r - s * s) / (2 * d * r));
  const double b = s * s * std::acos((d * d + s * s - r * r) / (2 * d * s));
  return a + b - 0.5 * std::sqrt((-d + r + s) * (d + r - s) * (d - r + s) * (d + r + s));
}

TEST(ClampedQuadrature, HasTheAreaOfTheBaseInsideTheBall) {
  const Hemisphere& h = hemisphere();
  ASSERT_GT(h.base.triangles.size(), 10u);
  const Eigen::Vector3d centre = contact_at(80 * pi / 180).point;
  const PatchQuadrature q = clamped_quadrature(h.base, centre, local_radius_m, local_radius_m / 16);
  double area = 0;
  for (std::size_t p = 0; p < q.points.size(); ++p) {
    EXPECT_LT((q.points[p] - centre).norm(), local_radius_m);
    EXPECT_NEAR(q.points[p].z(), 0.0, 1e-12);
    EXPECT_NEAR(q.normals[p].z(), -1.0, 1e-12) << "the base's outward normal";
    area += q.weights[p];
  }
  // The ball's trace on z = 0 is a disk of radius √(L² − z_c²) centred below the contact; the
  // base is the disk of radius R. Points dropped at the ball's edge (resolution L/16) and the
  // base's polygonal rim leave ~1 %.
  const double trace = std::sqrt(local_radius_m * local_radius_m - centre.z() * centre.z());
  const double exact = lens_area(trace, body_radius_m, std::hypot(centre.x(), centre.y()));
  EXPECT_NEAR(area, exact, 0.02 * exact) << "quadrature " << area << " m², lens " << exact << " m²";
  EXPECT_TRUE(clamped_quadrature(h.base, contact_at(0).point, local_radius_m, local_radius_m / 16).points.empty())
      << "the pole's ball does not reach the base";
}

TEST(ClampedQuadrature, RefusesATriangleWithAMissingVertex) {
  ClampedSurface bad{{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX()}, {Eigen::Vector3i(0, 1, 2)}};
  EXPECT_THROW(clamped_quadrature(bad, Eigen::Vector3d::Zero(), 1.0, 0.1), std::invalid_argument);
}

TEST(ClampedLocalModel, NearTheBaseTheBaseIsHeldAndJoinsTheReaction) {
  const Hemisphere& h = hemisphere();
  const ToolContact contact = contact_at(80 * pi / 180);
  LocalModelSettings settings;
  settings.formulation = Formulation::galerkin;
  settings.sprinkling.node_count = 100;
  settings.sprinkling.local_radius_m = local_radius_m;
  const geometry::Material material{10.0e3, 0.45};
  const LocalModel free_base = build_local_model(h.organ, contact, material, settings);
  const LocalModel held = build_local_model(h.organ, contact, material, settings, h.base);
  ASSERT_TRUE(free_base.ok()) << free_base.status;
  ASSERT_TRUE(held.ok()) << held.status;
  EXPECT_EQ(free_base.clamped_points, 0);
  EXPECT_GT(held.clamped_points, 100);
  EXPECT_FALSE(held.traction_available) << "the extraction shell (0.8 L) reaches the base 8.7 mm away";
  const Eigen::Vector3d push = 0.25e-3 * contact.direction;
  const LocalSolution a = solve_local_model(free_base, push), b = solve_local_model(held, push);
  ASSERT_EQ(b.status, "ok");
  const double free_force = a.forces.reaction_N.dot(contact.direction), held_force = b.forces.reaction_N.dot(contact.direction);
  std::printf("  contact at 80°: %.4e N with the base free, %.4e N held (%+.1f %%)\n", free_force, held_force,
              100 * (held_force / free_force - 1));
  EXPECT_GT(held_force, 1.02 * free_force) << "holding the base stiffens the contact";
  // The tool's force through the patch is balanced by the cut and the base together.
  const Eigen::Vector3d patch_force = held.galerkin.patch_tool_map * push - held.galerkin.patch_map * b.parameters;
  EXPECT_LT((patch_force - b.forces.reaction_N).norm(), 1e-9 * patch_force.norm());

  LocalModelSettings collocation = settings;
  collocation.formulation = Formulation::collocation;
  collocation.force.haptic_method = ForceMethod::traction_integral;
  const LocalModel refused = build_local_model(h.organ, contact, material, collocation, h.base);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.status.find("clamped"), std::string::npos) << refused.status;
}

TEST(ClampedLocalModel, AtThePoleTheBaseChangesNothing) {
  const Hemisphere& h = hemisphere();
  LocalModelSettings settings;
  settings.formulation = Formulation::galerkin;
  settings.sprinkling.node_count = 35;
  const geometry::Material material{10.0e3, 0.45};
  const LocalModel plain = build_local_model(h.organ, contact_at(0), material, settings);
  const LocalModel held = build_local_model(h.organ, contact_at(0), material, settings, h.base);
  ASSERT_TRUE(held.ok()) << held.status;
  EXPECT_EQ(held.clamped_points, 0);
  EXPECT_TRUE(held.traction_available);
  EXPECT_EQ(plain.tool_stiffness_N_per_m, held.tool_stiffness_N_per_m);
}

}  // namespace
}  // namespace touchstone::realtime::mfs
