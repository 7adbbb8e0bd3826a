// A user's organ surface meshed for the FEM reference: the hemisphere given as an STL file must
// come out as the B2 body (patch = the cap inside the cylinder, base = the disk, closed), and bad
// inputs must be refused naming the problem.
#include "support/expect_invalid_argument.hpp"
#include "support/temporary_directory.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/meshes/organ_body_mesh.hpp"
#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace touchstone::meshes {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr double body_radius = 0.05, tool_radius = 0.0025;

double area(const geometry::SurfaceData& s) {
  double total = 0;
  for (const auto& t : s.triangles)
    total += 0.5 * (s.vertices[static_cast<std::size_t>(t[1])] - s.vertices[static_cast<std::size_t>(t[0])])
                       .cross(s.vertices[static_cast<std::size_t>(t[2])] - s.vertices[static_cast<std::size_t>(t[0])])
                       .norm();
  return total;
}

class OrganBodyMesh : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    directory_ = new testing::TemporaryDirectory("organ_body_mesh");
    OrganParameters organ;
    organ.shape = OrganShape::hemisphere;
    organ.target_triangles = 4000;
    organ.hemisphere_radius_m = body_radius;
    write_organ_mesh(organ, directory_->path("hemisphere.stl"));
  }
  static void TearDownTestSuite() { delete directory_; }

  /// B2 at the pole, coarse (edge a/4), the base held by the plane rule z ≤ 0.
  static MeshParameters hemisphere() {
    MeshParameters p;
    p.benchmark = Benchmark::Organ;
    p.tool_radius_m = tool_radius;
    p.edge_size_m = tool_radius / 4;
    p.size_growth = 0.5;
    p.size_exponent = 0.75;
    p.max_size_m = 0.004;
    p.organ.surface_path = directory_->path("hemisphere.stl");
    p.organ.contact_point_m = {0.0, 0.0, body_radius};
    p.organ.tool_axis = {0.0, 0.0, -1.0};  // the sphere's normal (a facet's may tilt by a degree)
    p.organ.attachment.plane_normal = {0.0, 0.0, 1.0};
    return p;
  }
  static inline testing::TemporaryDirectory* directory_ = nullptr;
};

TEST_F(OrganBodyMesh, HemisphereFromAnStlFileIsTheB2Body) {
  const std::string path = directory_->path("hemisphere.msh");
  const MeshSummary summary = generate_mesh(hemisphere(), path);
  EXPECT_GT(summary.tetrahedron_count, 1000u);
  EXPECT_GT(summary.patch_triangle_count, 50u);

  const auto patch = read_msh_surface(path, {"tool_patch"});
  const auto base = read_msh_surface(path, {"base"});
  const auto all = read_msh_surface(path);
  // The patch: the cap inside the cylinder ρ < a (2πR(R − √(R² − a²)) on the sphere, the same
  // to 1e-4 on the input's facets), less the segments its rim polygon cuts off: chords across
  // triangles of edge ≤ √2 h subtend θ ≤ √2 h / a and lose at most θ²/6 of the area.
  const double cap = 2 * pi * body_radius * (body_radius - std::sqrt(body_radius * body_radius - tool_radius * tool_radius));
  const double h = tool_radius / 4;
  EXPECT_LT(area(patch), cap);
  EXPECT_GT(area(patch), cap * (1 - h * h / (3 * tool_radius * tool_radius)));
  // The rim: the patch's outer corners lie on the cylinder ρ = a around the tool axis through the
  // contact (the surface point nearest to the pole), moved or cut there exactly.
  const auto site = contact_site(hemisphere());
  const Eigen::Vector2d axis_point(site.point_m[0], site.point_m[1]);
  double largest_rho = 0;
  for (const auto& t : patch.triangles)
    for (int k = 0; k < 3; ++k)
      largest_rho = std::max(largest_rho, (patch.vertices[static_cast<std::size_t>(t[k])].head<2>() - axis_point).norm());
  EXPECT_NEAR(largest_rho, tool_radius, 1e-12);
  // The body is the input surface's, up to the chords of the longest surface edges ℓ (gmsh's
  // about 4 mm): the base polygon loses at most θ²/6 of its area (θ = ℓ/R), the enclosed volume
  // at most ℓ²/(4R²) (a polyhedron inscribed in a sphere), against the input's own measures.
  const auto input = read_surface_mesh(directory_->path("hemisphere.stl"), [] {
    SurfaceReadOptions weld;
    weld.weld_vertices = true;
    return weld;
  }());
  double input_base = 0;
  for (const auto& t : input.triangles) {
    const Eigen::Vector3d p0 = input.vertices[static_cast<std::size_t>(t[0])], p1 = input.vertices[static_cast<std::size_t>(t[1])],
                          p2 = input.vertices[static_cast<std::size_t>(t[2])];
    if (std::max({std::abs(p0.z()), std::abs(p1.z()), std::abs(p2.z())}) < 1e-9) input_base += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  double longest_edge = 0;
  for (const auto& t : all.triangles)
    for (int k = 0; k < 3; ++k)
      longest_edge = std::max(longest_edge, (all.vertices[static_cast<std::size_t>(t[k])] - all.vertices[static_cast<std::size_t>(t[(k + 1) % 3])]).norm());
  EXPECT_LT(longest_edge, 2 * hemisphere().max_size_m);
  const double theta = longest_edge / body_radius;
  EXPECT_LE(area(base), input_base * (1 + 1e-12));
  EXPECT_GT(area(base), input_base * (1 - theta * theta / 6));
  double volume = 0;
  for (const auto& t : all.triangles)
    volume += all.vertices[static_cast<std::size_t>(t[0])].dot(
                  all.vertices[static_cast<std::size_t>(t[1])].cross(all.vertices[static_cast<std::size_t>(t[2])])) / 6;
  const double input_volume = surface_statistics(input.vertices, input.triangles).volume_m3;
  EXPECT_LE(volume, input_volume * (1 + 1e-12));
  EXPECT_GT(volume, input_volume * (1 - theta * theta / 4));
  // The named groups the FEM reference expects, with the benchmark bodies' tags.
  std::vector<std::string> names;
  for (const auto& group : read_msh_physical_names(path)) names.push_back(group.name);
  for (const char* name : {"base", "tool_patch", "free", "tissue"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
}

TEST_F(OrganBodyMesh, ContactSiteIsTheNearestSurfacePointWithItsNormal) {
  MeshParameters p = hemisphere();
  p.organ.contact_point_m = {0.0, 0.0, body_radius + 0.003};  // 3 mm above the pole
  const ContactSite site = contact_site(p);
  EXPECT_NEAR(site.point_m[2], body_radius, 1e-4);
  EXPECT_NEAR(site.outward_normal[2], 1.0, 2e-3);
}

TEST_F(OrganBodyMesh, RefusesBadAttachmentsContactsAndToolSizes) {
  const std::string out = directory_->path("refused.msh");
  MeshParameters nothing = hemisphere();
  nothing.organ.attachment.plane_point_m = {0.0, 0.0, -0.01};
  testing::expect_invalid_argument([&] { generate_mesh(nothing, out); }, {"selects no triangle", "hemisphere.stl"});

  MeshParameters everything = hemisphere();
  everything.organ.attachment.plane_point_m = {0.0, 0.0, body_radius};
  testing::expect_invalid_argument([&] { generate_mesh(everything, out); }, {"touches the organ's attachment"});

  MeshParameters two_rules = hemisphere();
  two_rules.organ.attachment.msh_group = "base";
  testing::expect_invalid_argument([&] { generate_mesh(two_rules, out); }, {"set exactly one"});

  MeshParameters off_surface = hemisphere();
  off_surface.organ.contact_point_m = {0.0, 0.0, 0.06};  // 10 mm above the pole
  testing::expect_invalid_argument([&] { generate_mesh(off_surface, out); }, {"off the surface", "hemisphere.stl"});

  MeshParameters huge_tool = hemisphere();
  huge_tool.tool_radius_m = 0.04;
  huge_tool.edge_size_m = 0.01;
  huge_tool.max_size_m = 0.05;
  testing::expect_invalid_argument([&] { generate_mesh(huge_tool, out); }, {"too large for the organ", "unit scale"});
}

TEST_F(OrganBodyMesh, RefusesASurfaceWithAHoleNamingTheDefect) {
  const auto surface = read_surface_mesh(directory_->path("hemisphere.stl"));
  std::vector<Eigen::Vector3i> holed(surface.triangles.begin() + 1, surface.triangles.end());
  write_surface_mesh(directory_->path("holed.obj"), surface.vertices, holed);
  MeshParameters p = hemisphere();
  p.organ.surface_path = directory_->path("holed.obj");
  testing::expect_invalid_argument([&] { generate_mesh(p, directory_->path("holed.msh")); }, {"holed.obj", "not usable as an organ body", "not closed"});
}

}  // namespace
}  // namespace touchstone::meshes
