// Issue acceptance 5 (DESIGN.md §4.6): the four force extractions — traction integral over the
// patch, reaction on the cut, energy 2U/δ, the paper's tributary-scaled patch rows — must
// converge to each other as N grows on the B3 domain (hemisphere R = 50 mm ∩ ball(pole, 5a),
// clamped cut, frictionless punch a = 2.5 mm, δ = 0.25 mm; FEM reference 22.04 mN from
// studies/b3_reference.toml).
//
// Label open_acceptance: this asserts the target and FAILS today. Measured with the defaults
// (Galerkin, penalty) at N = 103, 201, 409: reaction 34.9, 29.8, 27.0 mN and energy 30.5,
// 27.7, 25.9 mN approach each other and the FEM from above, but the traction integral of
// σ(u_h)n (9.7, 14.8, 13.9 mN) and the paper's patch-node partition (9.6, 14.7, 14.4 mN) stay
// 35–55 % low: the smooth MLS field cannot carry the r^(−1/2) stress at the punch edge, which
// holds much of the force. (Least-squares collocation at N = 409: traction 8.9, paper 9.0,
// energy 42, reaction 200 mN.)
#include "hemisphere_fixture.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

constexpr double depth_m = 0.25e-3;
constexpr double fem_reference_N = 0.022038;  // touchstone fem studies/b3_reference.toml: frictionless, mean of 2 families (spread 0.2 %)

using testing::hemisphere;
using testing::pole_contact;
using testing::tool_radius_m;

TEST(ForceMethods, AgreeAsNodesAreAdded) {
  const ToolContact contact = pole_contact();
  const Material material{10.0e3, 0.45};
  std::vector<double> spread;
  for (const int n : {100, 200, 400}) {
    LocalModelSettings settings;
    settings.sprinkling.node_count = n;
    settings.sprinkling.local_radius_m = 5 * tool_radius_m;
    const LocalModel model = build_local_model(hemisphere(), contact, material, settings);
    ASSERT_TRUE(model.ok()) << model.status;
    const LocalSolution solution = solve_local_model(model, depth_m * contact.direction);
    ASSERT_EQ(solution.status, "ok");
    const ToolForces& f = solution.forces;
    const double forces[4] = {f.traction_integral_N.dot(contact.direction), f.reaction_N.dot(contact.direction),
                              f.energy_force_N, f.paper_partition_N.dot(contact.direction)};
    const auto [low, high] = std::minmax_element(forces, forces + 4);
    spread.push_back((*high - *low) / std::abs(forces[1]));
    std::printf("  N = %zu: traction %.4e N, reaction %.4e N, energy %.4e N, paper %.4e N; spread %.1f %%, "
                "traction vs FEM %+.1f %%\n",
                model.cloud.size(), forces[0], forces[1], forces[2], forces[3], 100 * spread.back(),
                100 * (forces[0] / fem_reference_N - 1));
  }
  EXPECT_LT(spread[2], spread[0]) << "the methods must approach each other";
  EXPECT_LT(spread[2], 0.05) << "within 5 % of each other at N ≈ 400";
}

}  // namespace
}  // namespace touchstone::realtime::mfs
