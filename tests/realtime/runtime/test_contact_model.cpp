// The force at haptic rate (realtime/runtime/contact_model): K_t U, unilateral contact, and the
// paper's extrapolation with its horizon.
#include "touchstone/realtime/runtime/contact_model.hpp"

#include <gtest/gtest.h>

namespace touchstone::realtime::runtime {
namespace {

ModelSnapshot model() {
  ModelSnapshot m;
  m.valid = true;
  m.model_id = 1;
  Eigen::Matrix3d k;
  k << 10, 1, 0, 1, 20, 2, 0, 2, 300;
  m.tool_stiffness_N_per_m = plain(k);
  m.contact_point_m = {0.01, 0.02, 0.03};
  m.direction = {0, 0, -1};
  m.local_radius_m = 0.0125;
  return m;
}

TEST(ContactModel, StiffnessForceIsKtTimesU) {
  const ModelSnapshot m = model();
  const Eigen::Vector3d tip = eigen(m.contact_point_m) + Eigen::Vector3d(0.001, -0.002, -0.003);
  const Eigen::Vector3d expected = eigen(m.tool_stiffness_N_per_m) * Eigen::Vector3d(0.001, -0.002, -0.003);
  ASSERT_LT(expected.z(), 0);  // pushes along d = −z
  EXPECT_TRUE(stiffness_force_N(m, tip).isApprox(expected, 1e-15));
  EXPECT_NEAR(penetration_depth_m(m, tip), 0.003, 1e-15);
  EXPECT_NEAR(tangential_offset_m(m, tip), std::sqrt(5e-6), 1e-15);
}

TEST(ContactModel, TissueDoesNotPull) {
  const ModelSnapshot m = model();
  const Eigen::Vector3d above = eigen(m.contact_point_m) + Eigen::Vector3d(0, 0, 0.001);
  EXPECT_EQ(stiffness_force_N(m, above), Eigen::Vector3d::Zero());
  EXPECT_EQ(push_only(Eigen::Vector3d(1, 0, 0.1), Eigen::Vector3d(0, 0, -1)), Eigen::Vector3d::Zero());
}

TEST(ContactModel, ExtrapolationIsLinearUpToTheHorizon) {
  ModelSnapshot m = model();
  EXPECT_EQ(extrapolated_force_N(m, 1.0, 0.01), Eigen::Vector3d::Zero()) << "no force yet";
  m.force_N = {0, 0, -1.0};
  m.force_time_s = 1.0;
  EXPECT_EQ(extrapolated_force_N(m, 1.003, 0.01), Eigen::Vector3d(0, 0, -1.0)) << "one force: held";
  m.previous_force_N = {0, 0, -0.9};
  m.previous_force_time_s = 0.995;
  EXPECT_NEAR(extrapolated_force_N(m, 1.002, 0.01).z(), -1.04, 1e-12);  // slope −20 N/s
  EXPECT_NEAR(extrapolated_force_N(m, 1.050, 0.01).z(), -1.2, 1e-12);   // capped at 10 ms
  EXPECT_NEAR(extrapolated_force_N(m, 0.990, 0.01).z(), -1.0, 1e-12);   // never backwards
  m.force_N = {0, 0, -0.05};  // falling: the extrapolation would cross zero and pull
  EXPECT_EQ(extrapolated_force_N(m, 1.005, 0.01), Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace touchstone::realtime::runtime
