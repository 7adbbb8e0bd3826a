// Richardson extrapolation on sequences with a known limit and order.
#include "touchstone/fem/richardson.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace touchstone::fem {
namespace {

std::vector<double> sequence(double limit, double constant, double order, int levels) {
  std::vector<double> values;
  for (int k = 0; k < levels; ++k) values.push_back(limit + constant * std::pow(0.5, order * k));
  return values;
}

TEST(Richardson, RecoversTheLimitAndOrderOfAnExactPowerLaw) {
  for (const double order : {1.0, 1.5, 2.0, 2.5}) {
    const RichardsonEstimate r = richardson_extrapolate(sequence(16.3, 1.2, order, 3), 2.0, 1.0);
    EXPECT_NEAR(r.observed_order, order, 1e-10);
    EXPECT_NEAR(r.extrapolated, 16.3, 1e-10);
    const double finest = 16.3 + 1.2 * std::pow(0.25, order);
    EXPECT_NEAR(r.finest_relative_error, (finest - 16.3) / 16.3, 1e-12);
    EXPECT_TRUE(r.asymptotic);
    // The uncertainty compares with the theoretical order 1: zero exactly when they agree.
    if (order == 1.0) {
      EXPECT_NEAR(r.extrapolated_relative_uncertainty, 0.0, 1e-12);
    }
    if (order > 1.0) {
      EXPECT_GT(r.extrapolated_relative_uncertainty, 0.0);
    }
  }
}

// An observed order far above what theory allows (here 4 against 1) means the meshes are not in
// the asymptotic range: the value is still extrapolated, but flagged.
TEST(Richardson, FlagsAnOrderOutsideTheTheoreticalRange) {
  const RichardsonEstimate r = richardson_extrapolate(sequence(1.0, 1.0, 4.0, 3), 2.0, 1.0);
  EXPECT_NEAR(r.observed_order, 4.0, 1e-10);
  EXPECT_FALSE(r.asymptotic);
}

TEST(Richardson, UsesTheThreeFinestValues) {
  std::vector<double> values = sequence(2.0, 5.0, 2.0, 3);
  values.insert(values.begin(), 100.0);  // a wild coarse level must not matter
  EXPECT_NEAR(richardson_extrapolate(values, 2.0, 2.0).extrapolated, 2.0, 1e-12);
}

TEST(Richardson, NonMonotoneSequenceFallsBackToTheFinestValue) {
  const RichardsonEstimate r = richardson_extrapolate({1.0, 1.2, 1.1}, 2.0, 1.0);
  EXPECT_TRUE(std::isnan(r.observed_order));
  EXPECT_FALSE(r.asymptotic);
  EXPECT_EQ(r.extrapolated, 1.1);
  EXPECT_NEAR(r.finest_relative_error, 0.1 / 1.1, 1e-15);
}

TEST(Richardson, RejectsTooFewValuesOrABadRatio) {
  EXPECT_THROW(richardson_extrapolate({1.0, 2.0}, 2.0, 1.0), std::invalid_argument);
  EXPECT_THROW(richardson_extrapolate({1.0, 2.0, 3.0}, 1.0, 1.0), std::invalid_argument);
}

}  // namespace
}  // namespace touchstone::fem
