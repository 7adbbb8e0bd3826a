// The tool patch cut into triangle surfaces, against the exact circle: on a plane the patch is
// the disk of radius a, on a sphere the cap inside the cylinder (area 2πR(R − √(R² − a²))).
#include "touchstone/meshes/tool_patch_imprint.hpp"

#include "touchstone/geometry/icosphere.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace touchstone::meshes {
namespace {

constexpr double pi = 3.14159265358979323846;

/// A flat square [−L, L]² at z = 0 of 2·n² right triangles (normal +z), slightly sheared so that
/// no vertex sits exactly on a circle of round radius.
geometry::TriangleMeshData flat_square(double half_width, int n) {
  geometry::TriangleMeshData mesh;
  const double h = 2 * half_width / n;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) mesh.vertices.emplace_back(-half_width + i * h + 0.013 * h * j / n, -half_width + j * h, 0.0);
  const auto id = [n](int i, int j) { return j * (n + 1) + i; };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      mesh.triangles.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
      mesh.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
    }
  return mesh;
}

double signed_area_z(const ImprintedSurface& s, std::size_t i) {
  const Eigen::Vector3i& t = s.triangles[i];
  const Eigen::Vector3d& p = s.vertices[static_cast<std::size_t>(t[0])];
  return 0.5 * (s.vertices[static_cast<std::size_t>(t[1])] - p).cross(s.vertices[static_cast<std::size_t>(t[2])] - p).z();
}

/// Every undirected edge's triangle count: a closed surface has 2 everywhere.
std::map<std::pair<int, int>, int> edge_counts(const std::vector<Eigen::Vector3i>& triangles) {
  std::map<std::pair<int, int>, int> count;
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) ++count[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  return count;
}

TEST(ToolPatchImprint, FlatDiskAreaConvergesToTheCircleAtSecondOrder) {
  const double a = 2.5e-3;
  ToolPatchCylinder tool;
  tool.contact_point_m = {1e-4, -2e-4, 0.0};
  tool.axis = {0.0, 0.0, -1.0};
  tool.radius_m = a;
  double previous_error = 0;
  for (const int n : {16, 32, 64}) {
    const auto mesh = flat_square(3 * a, n);
    const ImprintedSurface s = imprint_tool_patch(mesh.vertices, mesh.triangles, tool);
    // Rim points lie on the circle to rounding.
    EXPECT_LT(s.rim_relative_deviation, 1e-12);
    ASSERT_GT(s.rim_vertices.size(), 8u);
    // Nothing is lost or flipped: the pieces cover the square with the input's orientation.
    double total = 0;
    for (std::size_t i = 0; i < s.triangles.size(); ++i) {
      EXPECT_GT(signed_area_z(s, i), 0) << "triangle " << i;
      total += signed_area_z(s, i);
    }
    EXPECT_NEAR(total, 36 * a * a, 1e-12 * 36 * a * a);
    // An inscribed polygon: below the disk, by at most θ²/6 for chords subtending θ ≤ √2 h / a
    // (a chord crosses one triangle, whose longest edge is √2 h), and second order in h.
    const double error = (pi * a * a - s.patch_area_m2) / (pi * a * a);
    const double h = 6 * a / n;
    EXPECT_GT(error, 0) << "n = " << n;
    EXPECT_LT(error, h * h / (3 * a * a)) << "n = " << n;
    if (previous_error > 0) {
      EXPECT_NEAR(std::log2(previous_error / error), 2.0, 0.35) << "n = " << n;
    }
    previous_error = error;
    // Patch triangles lie inside the cylinder, the others outside (checked at their centroids).
    for (std::size_t i = 0; i < s.triangles.size(); ++i) {
      const Eigen::Vector3i& t = s.triangles[i];
      const Eigen::Vector3d centroid = (s.vertices[static_cast<std::size_t>(t[0])] + s.vertices[static_cast<std::size_t>(t[1])] +
                                        s.vertices[static_cast<std::size_t>(t[2])]) / 3;
      const double rho = (centroid - tool.contact_point_m).head<2>().norm();
      EXPECT_EQ(s.in_patch[i] != 0, rho < a) << "triangle " << i << " at rho = " << rho;
    }
  }
}

TEST(ToolPatchImprint, SphereCapOnTheNearSideOnlyAndTheSurfaceStaysClosed) {
  const double radius = 0.01, a = 2.5e-3;
  const auto sphere = geometry::icosphere(5, radius);
  ToolPatchCylinder tool;
  tool.contact_point_m = {0.0, 0.0, radius};
  tool.axis = {0.0, 0.0, -1.0};
  tool.radius_m = a;
  const ImprintedSurface s = imprint_tool_patch(sphere.vertices, sphere.triangles, tool);
  EXPECT_LT(s.rim_relative_deviation, 1e-12);
  EXPECT_GT(s.split_triangle_count, 0u);
  // The cylinder also passes through the south pole: that sheet is not the patch.
  for (std::size_t i = 0; i < s.triangles.size(); ++i)
    if (s.in_patch[i]) {
      for (int k = 0; k < 3; ++k) EXPECT_GT(s.vertices[static_cast<std::size_t>(s.triangles[i][k])].z(), 0.9 * radius);
    }
  // The exact cap inside the cylinder; the faceted sphere (edges ≈ R/30) is within 1 % of it.
  const double cap = 2 * pi * radius * (radius - std::sqrt(radius * radius - a * a));
  EXPECT_NEAR(s.patch_area_m2, cap, 0.01 * cap);
  // Closed and consistently oriented: every edge twice, in opposite directions; outward normals.
  for (const auto& [edge, count] : edge_counts(s.triangles)) EXPECT_EQ(count, 2) << edge.first << "-" << edge.second;
  for (const auto& t : s.triangles) {
    const Eigen::Vector3d p = s.vertices[static_cast<std::size_t>(t[0])], q = s.vertices[static_cast<std::size_t>(t[1])],
                          r = s.vertices[static_cast<std::size_t>(t[2])];
    EXPECT_GT((q - p).cross(r - p).dot(p + q + r), 0);
  }
}

TEST(ToolPatchImprint, RefusesASurfaceCoarserThanThePatchAndAnOpenPatch) {
  ToolPatchCylinder tool;
  tool.contact_point_m = {0.0, 0.0, 0.01};
  tool.radius_m = 1e-4;  // far below the icosahedron's 10 mm edges: no corner inside
  const auto coarse = geometry::icosphere(0, 0.01);
  try {
    imprint_tool_patch(coarse.vertices, coarse.triangles, tool);
    FAIL() << "a patch between the corners was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("too coarse"), std::string::npos) << e.what();
  }
  // A flat square narrower than the patch: the patch would reach the square's edge.
  const auto small = flat_square(1e-3, 8);
  tool.contact_point_m = Eigen::Vector3d::Zero();
  tool.radius_m = 2e-3;
  try {
    imprint_tool_patch(small.vertices, small.triangles, tool);
    FAIL() << "an open patch was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("not enclosed"), std::string::npos) << e.what();
  }
  tool.radius_m = -1;
  EXPECT_THROW(imprint_tool_patch(small.vertices, small.triangles, tool), std::invalid_argument);
}

}  // namespace
}  // namespace touchstone::meshes
