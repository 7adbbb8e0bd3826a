// Probe points: identical for both models, on the surface or the tool axis where they say.
#include "touchstone/studies/fem_reference/probes.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace touchstone::studies {
namespace {

TEST(Probes, HemisphereProbesLieOnTheAxisAndTheSphere) {
  meshes::MeshParameters g;
  g.benchmark = meshes::Benchmark::B2;
  const auto probes = indentation_probes(g, {0.0, 0.0, -1.0});
  ASSERT_EQ(probes.size(), 14u);
  for (const auto& p : probes) {
    if (p.name.rfind("axis", 0) == 0) {
      EXPECT_NEAR(p.position_m.head<2>().norm(), 0.0, 1e-15) << p.name;
      EXPECT_LT(p.position_m.z(), g.body_radius_m);
    } else {
      EXPECT_NEAR(p.position_m.norm(), g.body_radius_m, 1e-15) << p.name;
    }
  }
  EXPECT_EQ(probes.front().name, "axis_0.25a");
  EXPECT_NEAR(probes[5].position_m.z(), g.body_radius_m - 8 * g.tool_radius_m, 1e-15);  // axis_8a
}

TEST(Probes, OffPoleContactRotatesTheProbes) {
  meshes::MeshParameters g;
  g.benchmark = meshes::Benchmark::B5;
  g.contact_polar_angle_rad = 0.5;
  const Eigen::Vector3d n = outward_normal(g);
  EXPECT_NEAR((contact_point(g) - g.body_radius_m * n).norm(), 0.0, 1e-15);
  for (const auto& p : indentation_probes(g, -n)) {
    if (p.name.rfind("meridian", 0) == 0) {
      EXPECT_NEAR(p.position_m.norm(), g.body_radius_m, 1e-15) << p.name;
    }
  }
}

TEST(Probes, CylinderProbesLieOnTheFlatTopAndTheAxisBelowTheOrigin) {
  meshes::MeshParameters g;
  g.benchmark = meshes::Benchmark::B1;
  g.body_radius_m = 0.05;
  EXPECT_NEAR(contact_point(g).norm(), 0.0, 1e-15);
  EXPECT_NEAR((outward_normal(g) - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-15);
  const auto probes = indentation_probes(g, {0.0, 0.0, -1.0});
  ASSERT_EQ(probes.size(), 14u);
  for (const auto& p : probes) {
    if (p.name.rfind("axis", 0) == 0) {
      EXPECT_NEAR(p.position_m.head<2>().norm(), 0.0, 1e-15) << p.name;
      EXPECT_LT(p.position_m.z(), 0.0) << p.name;
    } else {
      // The "meridian" of a flat top: the radial line along +x on z = 0.
      EXPECT_EQ(p.position_m.z(), 0.0) << p.name;
      EXPECT_EQ(p.position_m.y(), 0.0) << p.name;
      EXPECT_GE(p.position_m.x(), 0.0) << p.name;
    }
  }
  EXPECT_EQ(probes.back().name, "meridian_8a");
  EXPECT_NEAR(probes.back().position_m.x(), 8 * g.tool_radius_m, 1e-15);
}

TEST(Probes, LocalDomainDropsProbesOutsideTheBall) {
  meshes::MeshParameters g;
  g.benchmark = meshes::Benchmark::B3;
  g.local_radius_m = 5 * g.tool_radius_m;
  for (const auto& p : indentation_probes(g, {0.0, 0.0, -1.0}))
    EXPECT_LT((p.position_m - contact_point(g)).norm(), g.local_radius_m) << p.name;
}

}  // namespace
}  // namespace touchstone::studies
