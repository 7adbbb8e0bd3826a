// The safety filter (realtime/haptics/safety_filter): whatever is requested — NaN, spikes, stale
// model data, a disconnect — the output never exceeds the clamp and never changes faster than
// the rate limit, except for the immediate zero of a disconnect or shutdown.
#include "touchstone/realtime/haptics/safety_filter.hpp"

#include "support/expect_invalid_argument.hpp"
#include "touchstone/realtime/hand_motion/tremor_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace touchstone::realtime::haptics {
namespace {

constexpr double dt = 1e-3;
constexpr double nan = std::numeric_limits<double>::quiet_NaN();
constexpr double inf = std::numeric_limits<double>::infinity();

SafetySettings settings() {
  SafetySettings s;
  s.max_force_N = 3.0;
  s.max_rate_N_per_s = 100.0;  // 0.1 N per 1 ms tick
  s.stale_after_s = 0.05;
  return s;
}

SafetyInput at(int tick) {
  SafetyInput input;
  input.time_s = tick * dt;
  return input;
}

TEST(SafetyFilter, PassesABenignForceUntouched) {
  SafetyFilter filter(settings());
  for (int k = 0; k < 1000; ++k) {
    const Eigen::Vector3d request(0, 0, 1.5 * std::sin(k * dt * 3.0));  // |dF/dt| ≤ 4.5 N/s
    const Eigen::Vector3d out = filter.filter(request, at(k));
    EXPECT_EQ(out, request) << "tick " << k;
  }
  EXPECT_EQ(filter.counters().interventions(), 0);
}

TEST(SafetyFilter, ClampsTheMagnitudeAndRampsAtTheRateLimit) {
  SafetyFilter filter(settings());
  filter.filter(Eigen::Vector3d::Zero(), at(0));
  double previous = 0;
  for (int k = 1; k <= 100; ++k) {
    const double out = filter.filter(Eigen::Vector3d(0, 50.0, 0), at(k)).norm();
    EXPECT_LE(out, 3.0 + 1e-12);
    EXPECT_LE(out - previous, 0.1 + 1e-12);
    previous = out;
  }
  EXPECT_NEAR(previous, 3.0, 1e-12);  // 30 ticks of 0.1 N reach the clamp
  EXPECT_EQ(filter.counters().clamped, 100);
  EXPECT_EQ(filter.counters().rate_limited, 30);
}

TEST(SafetyFilter, ReplacesNanAndInfByZeroAndRampsDown) {
  SafetyFilter filter(settings());
  filter.filter(Eigen::Vector3d::Zero(), at(0));
  for (int k = 1; k <= 20; ++k) filter.filter(Eigen::Vector3d(1.0, 0, 0), at(k));
  EXPECT_NEAR(filter.output().x(), 1.0, 1e-12);
  const Eigen::Vector3d a = filter.filter(Eigen::Vector3d(nan, 0, 0), at(21));
  const Eigen::Vector3d b = filter.filter(Eigen::Vector3d(0, inf, 0), at(22));
  EXPECT_TRUE(a.allFinite());
  EXPECT_TRUE(b.allFinite());
  EXPECT_NEAR(a.x(), 0.9, 1e-12);  // toward zero at 0.1 N per tick, not a sudden drop
  EXPECT_NEAR(b.x(), 0.8, 1e-12);
  EXPECT_EQ(filter.counters().non_finite, 2);
}

TEST(SafetyFilter, WatchdogRampsToZeroOnStaleModelData) {
  SafetyFilter filter(settings());
  filter.filter(Eigen::Vector3d::Zero(), at(0));
  for (int k = 1; k <= 20; ++k) filter.filter(Eigen::Vector3d(0, 0, -2.0), at(k));
  ASSERT_NEAR(filter.output().z(), -2.0, 1e-12);
  int ticks_to_zero = 0;
  for (int k = 21; filter.output().norm() > 0; ++k, ++ticks_to_zero) {
    SafetyInput input = at(k);
    input.model_age_s = 0.2;  // older than stale_after_s = 0.05
    filter.filter(Eigen::Vector3d(0, 0, -2.0), input);
    ASSERT_LT(ticks_to_zero, 1000);
  }
  EXPECT_EQ(ticks_to_zero, 20);  // 2 N at 0.1 N per tick
  EXPECT_EQ(filter.counters().stale, 20);
  SafetyInput nan_age = at(100);
  nan_age.model_age_s = nan;
  filter.filter(Eigen::Vector3d(0, 0, -2.0), nan_age);
  EXPECT_EQ(filter.output().norm(), 0.0) << "a NaN age counts as stale";
}

TEST(SafetyFilter, ZeroesAtOnceOnDisconnectAndShutdown) {
  SafetyFilter filter(settings());
  filter.filter(Eigen::Vector3d::Zero(), at(0));
  for (int k = 1; k <= 30; ++k) filter.filter(Eigen::Vector3d(3.0, 0, 0), at(k));
  SafetyInput gone = at(31);
  gone.connected = false;
  EXPECT_EQ(filter.filter(Eigen::Vector3d(3.0, 0, 0), gone), Eigen::Vector3d::Zero());
  EXPECT_EQ(filter.counters().disconnect_zero, 1);
  for (int k = 32; k <= 40; ++k) filter.filter(Eigen::Vector3d(1.0, 0, 0), at(k));
  SafetyInput shutdown = at(41);
  shutdown.shutting_down = true;
  EXPECT_EQ(filter.filter(Eigen::Vector3d(1.0, 0, 0), shutdown), Eigen::Vector3d::Zero());
  EXPECT_EQ(filter.counters().disconnect_zero, 2);
}

TEST(SafetyFilter, FirstTickAndBackwardClockGiveNoAllowance) {
  SafetyFilter filter(settings());
  EXPECT_EQ(filter.filter(Eigen::Vector3d(1, 0, 0), at(5)), Eigen::Vector3d::Zero());
  filter.filter(Eigen::Vector3d(1, 0, 0), at(6));
  EXPECT_NEAR(filter.output().x(), 0.1, 1e-12);
  filter.filter(Eigen::Vector3d(1, 0, 0), at(3));  // the clock ran backwards
  EXPECT_NEAR(filter.output().x(), 0.1, 1e-12);
  SafetyInput nan_time = at(7);
  nan_time.time_s = nan;
  EXPECT_TRUE(filter.filter(Eigen::Vector3d(1, 0, 0), nan_time).allFinite());
}

// Whatever reaches the filter, the device gets a clamped, rate-limited force: 200,000 ticks of
// injected faults — NaN, Inf, spikes of 10³–10⁹ N, stale data, disconnects — and the two
// invariants hold on every tick.
TEST(SafetyFilter, NeverExceedsTheClampOrTheRateLimitUnderInjectedFaults) {
  const SafetySettings s = settings();
  SafetyFilter filter(s);
  hand_motion::RandomStream random(42);
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  long long disconnects = 0;
  for (int k = 0; k < 200000; ++k) {
    Eigen::Vector3d request(random.gaussian(), random.gaussian(), random.gaussian());
    const double fault = random.uniform();
    if (fault < 0.02) request.x() = nan;
    else if (fault < 0.04) request.y() = -inf;
    else if (fault < 0.10) request *= std::pow(10.0, 3 + 6 * random.uniform());  // spike
    SafetyInput input = at(k);
    input.model_age_s = random.uniform() < 0.05 ? 1.0 : 0.0;
    input.connected = random.uniform() > 0.001;
    const Eigen::Vector3d out = filter.filter(request, input);
    ASSERT_TRUE(out.allFinite()) << "tick " << k;
    ASSERT_LE(out.norm(), s.max_force_N * (1 + 1e-12)) << "tick " << k;
    if (!input.connected) {
      ASSERT_EQ(out, Eigen::Vector3d::Zero()) << "tick " << k;
      ++disconnects;
    } else {
      ASSERT_LE((out - previous).norm(), s.max_rate_N_per_s * dt * (1 + 1e-9)) << "tick " << k;
    }
    previous = out;
  }
  const SafetyCounters& c = filter.counters();
  EXPECT_GT(disconnects, 100);
  EXPECT_GT(c.non_finite, 5000);
  EXPECT_GT(c.stale, 5000);
  EXPECT_GT(c.clamped, 10000);
  EXPECT_GT(c.rate_limited, 10000);
}

TEST(SafetyFilter, InvalidSettingsNameTheField) {
  SafetySettings s = settings();
  s.max_force_N = 0;
  testing::expect_invalid_argument([&] { SafetyFilter filter(s); }, {"max_force_N"});
  s = settings();
  s.max_rate_N_per_s = nan;
  testing::expect_invalid_argument([&] { SafetyFilter filter(s); }, {"max_rate_N_per_s"});
  s = settings();
  s.stale_after_s = -1;
  testing::expect_invalid_argument([&] { SafetyFilter filter(s); }, {"stale_after_s"});
}

}  // namespace
}  // namespace touchstone::realtime::haptics
