// Node sprinkling on a real closed surface (the gmsh B2 hemisphere): counts, placement of each
// node kind, determinism, bad input; and the tool-patch quadrature.
#include "hemisphere_fixture.hpp"
#include "touchstone/realtime/mfs/local_surface.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double radius_m = testing::hemisphere_radius_m, tool_radius_m = testing::tool_radius_m;

using testing::hemisphere;
using testing::pole_contact;

class Sprinkling : public ::testing::TestWithParam<Layout> {};

TEST_P(Sprinkling, NodesSitWhereTheirKindSays) {
  SprinklingSettings settings;
  settings.layout = GetParam();
  settings.node_count = 150;
  settings.local_radius_m = 5 * tool_radius_m;
  const NodeCloud cloud = sprinkle_nodes(hemisphere(), pole_contact(), settings);
  // Distances are measured from the contact point on the faceted surface.
  const Eigen::Vector3d centre = hemisphere().project(pole_contact().point).point;
  EXPECT_NEAR(static_cast<double>(cloud.size()), settings.node_count, 0.25 * settings.node_count);
  int counts[4] = {0, 0, 0, 0};
  for (std::size_t j = 0; j < cloud.size(); ++j) {
    const Eigen::Vector3d& x = cloud.positions[j];
    const double rho = (x - centre).norm(), on_sphere = std::abs(x.norm() - radius_m);
    ++counts[static_cast<int>(cloud.kinds[j])];
    EXPECT_GT(cloud.radii[j], 0);
    EXPECT_LE(rho, settings.local_radius_m * (1 + 1e-9));
    switch (cloud.kinds[j]) {
      case NodeKind::tool_patch:
        EXPECT_LT(rho, tool_radius_m * 1.01);
        EXPECT_LT(on_sphere, 1e-4);  // on the faceted surface
        break;
      case NodeKind::free_surface:
        EXPECT_GT(rho, tool_radius_m);
        EXPECT_LT(on_sphere, 1e-4);
        EXPECT_NEAR(cloud.normals[j].dot(x.normalized()), 1.0, 0.02);
        break;
      case NodeKind::cut: EXPECT_NEAR(rho, settings.local_radius_m, 1e-9); break;
      case NodeKind::interior:
        EXPECT_LT(x.norm(), radius_m - 1e-5);
        EXPECT_TRUE(hemisphere().contains(x));
        break;
    }
  }
  // The tip, then ≥ 2 rings of ≥ ring_nodes each; the last ring sits on the patch edge.
  EXPECT_GE(counts[static_cast<int>(NodeKind::tool_patch)], 1 + 2 * settings.ring_nodes);
  int on_edge = 0;
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (cloud.kinds[j] == NodeKind::tool_patch && std::abs((cloud.positions[j] - centre).norm() - tool_radius_m) < 0.01 * tool_radius_m)
      ++on_edge;
  EXPECT_GE(on_edge, settings.ring_nodes);
  for (int kind = 0; kind < 4; ++kind) EXPECT_GT(counts[kind], 0) << "kind " << kind;
}

INSTANTIATE_TEST_SUITE_P(Layouts, Sprinkling,
                         ::testing::Values(Layout::radial_shells, Layout::quasi_random, Layout::lattice));

// The enriched model's even cloud has exactly the nodes asked for (the interior makes up what the
// surface spiral's outer ring and the cut lattice lose; it used to come out about a tenth short),
// every one inside the local ball, with all four kinds present.
TEST(EvenSprinkling, HoldsTheRequestedCount) {
  const double length = 5 * tool_radius_m;
  const Eigen::Vector3d centre = hemisphere().project(pole_contact().point).point;
  for (const std::uint64_t seed : {1u, 2u, 3u})
    for (const int count : {10, 30, 45, 60, 100, 200, 300}) {
      const NodeCloud cloud = sprinkle_even_nodes(hemisphere(), pole_contact(), count, length, seed);
      EXPECT_EQ(static_cast<int>(cloud.size()), count) << "seed " << seed;
      int kinds[4] = {0, 0, 0, 0};
      for (std::size_t j = 0; j < cloud.size(); ++j) {
        ++kinds[static_cast<int>(cloud.kinds[j])];
        EXPECT_LE((cloud.positions[j] - centre).norm(), length * (1 + 1e-9));
        EXPECT_TRUE(cloud.kinds[j] != NodeKind::interior || hemisphere().contains(cloud.positions[j]));
      }
      for (int kind = 0; kind < 4; ++kind) EXPECT_GT(kinds[kind], 0) << "N = " << count << ", kind " << kind;
    }
}

TEST(Sprinkling, IsDeterministicForASeed) {
  SprinklingSettings settings;
  settings.node_count = 80;
  const NodeCloud a = sprinkle_nodes(hemisphere(), pole_contact(), settings);
  const NodeCloud b = sprinkle_nodes(hemisphere(), pole_contact(), settings);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t j = 0; j < a.size(); ++j) EXPECT_EQ(a.positions[j], b.positions[j]);
  settings.seed = 2;
  const NodeCloud c = sprinkle_nodes(hemisphere(), pole_contact(), settings);
  bool differs = c.size() != a.size();
  for (std::size_t j = 0; !differs && j < a.size(); ++j) differs = a.positions[j] != c.positions[j];
  EXPECT_TRUE(differs);
}

TEST(Sprinkling, RowsFollowTheContactCondition) {
  SprinklingSettings settings;
  settings.node_count = 60;
  ToolContact contact = pole_contact();
  contact.condition = geometry::ContactCondition::frictionless;
  const NodeCloud frictionless = sprinkle_nodes(hemisphere(), contact, settings);
  // Tip node: u·d prescribed through the tool column, two tangential traction rows.
  EXPECT_EQ(frictionless.rows[0][0].type, CollocationRow::Type::dirichlet);
  EXPECT_EQ(frictionless.rows[0][0].tool, contact.direction);
  EXPECT_EQ(frictionless.rows[0][1].type, CollocationRow::Type::traction);
  EXPECT_NEAR(frictionless.rows[0][1].direction.dot(contact.direction), 0.0, 1e-15);
  contact.condition = geometry::ContactCondition::bonded;
  const NodeCloud bonded = sprinkle_nodes(hemisphere(), contact, settings);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(bonded.rows[0][k].tool, Eigen::Vector3d::Unit(k));
}

TEST(Sprinkling, BadInputIsNamed) {
  SprinklingSettings settings;
  settings.node_count = 5;
  EXPECT_THROW(sprinkle_nodes(hemisphere(), pole_contact(), settings), std::invalid_argument);
  settings = SprinklingSettings{};
  ToolContact off_surface = pole_contact();
  off_surface.point.z() += 0.01;
  try {
    sprinkle_nodes(hemisphere(), off_surface, settings);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ToolContact.point"), std::string::npos) << e.what();
  }
  ToolContact nan_direction = pole_contact();
  nan_direction.direction.x() = std::nan("");
  EXPECT_THROW(sprinkle_nodes(hemisphere(), nan_direction, settings), std::invalid_argument);
}

// Whether a contact is on the organ is judged on its triangles, not on the smooth surface the
// enriched model fits there: on a faceted organ the two differ by more than a fine tip's a/10,
// and a contact point on a facet must still be accepted. A point well off the triangles is not.
TEST(EvenSprinkling, AContactOnAFacetIsOnTheOrganForAFineTip) {
  const double fine_tip_m = 5e-5, length_m = 5 * tool_radius_m;
  // 20° from the pole, where the fixture's triangles are coarse (the sagitta of a 4 mm edge on
  // R = 50 mm is 40 µm).
  const double polar = 20 * 3.14159265358979323846 / 180;
  const Eigen::Vector3d on_sphere = radius_m * Eigen::Vector3d(std::sin(polar), 0.0, std::cos(polar));
  ToolContact contact = pole_contact();
  contact.radius_m = fine_tip_m;
  contact.point = hemisphere().project(on_sphere).point;
  contact.direction = -on_sphere.normalized();
  const LocalSurface surface(hemisphere(), contact.point, 1.3 * length_m);
  ASSERT_TRUE(surface.fitted());
  // The premise: the fitted surface's point is farther from the facet's than a/10.
  ASSERT_GT((surface.centre() - contact.point).norm(), 0.1 * fine_tip_m);
  EXPECT_LT(surface.contact_offset_m(), 1e-9);
  const NodeCloud cloud = sprinkle_even_nodes(surface, contact, 30, length_m, 1);
  EXPECT_EQ(cloud.size(), 30u);

  ToolContact off_organ = contact;
  off_organ.point += 0.2 * fine_tip_m * on_sphere.normalized();
  const LocalSurface off_surface(hemisphere(), off_organ.point, 1.3 * length_m);
  try {
    sprinkle_even_nodes(off_surface, off_organ, 30, length_m, 1);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ToolContact.point is not on the organ surface"), std::string::npos) << e.what();
  }
}

/// A flat-topped organ (B1: cylinder, top face z = 0) so that the patch is a plane disk.
const geometry::TriangleSurface& cylinder() {
  static const geometry::TriangleSurface surface = [] {
    meshes::MeshParameters g;
    g.benchmark = meshes::Benchmark::B1;
    g.body_radius_m = 0.02;
    g.edge_size_m = 0.0005;
    g.size_growth = 0.3;
    g.max_size_m = 0.004;
    const std::string path = "sprinkling_cylinder_" + std::to_string(getpid()) + ".msh";
    meshes::generate_mesh(g, path);
    geometry::TriangleSurface surface = meshes::load_msh_surface(path);
    std::remove(path.c_str());
    return surface;
  }();
  return surface;
}

// The weights integrate the patch area πa², and the flat-punch pressure profile
// (a² − r²)^(−1/2), singular at the edge, to 2πa: the r = a sin φ rule absorbs the singularity.
TEST(PatchQuadrature, IntegratesTheSingularPunchPressure) {
  ToolContact contact;
  contact.point = Eigen::Vector3d::Zero();
  contact.radius_m = tool_radius_m;
  const PatchQuadrature q = patch_quadrature(cylinder(), contact);
  double area = 0, singular = 0;
  for (std::size_t p = 0; p < q.points.size(); ++p) {
    area += q.weights[p];
    singular += q.weights[p] / std::sqrt(tool_radius_m * tool_radius_m - q.points[p].head<2>().squaredNorm());
    EXPECT_NEAR(q.normals[p].z(), 1.0, 1e-12);
  }
  EXPECT_NEAR(area, M_PI * tool_radius_m * tool_radius_m, 1e-12 * area);
  EXPECT_NEAR(singular, 2 * M_PI * tool_radius_m, 1e-10 * singular);
}

}  // namespace
}  // namespace touchstone::realtime::mfs
