// The tissue material and the tool's contact condition that both models share: the Lamé
// constants, validation naming the field and value, and the names configs use.
#include "support/expect_invalid_argument.hpp"
#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/geometry/material.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace touchstone::geometry {
namespace {

using touchstone::testing::expect_invalid_argument;

TEST(Material, LameConstantsOfTheDefaultTissue) {
  const Material tissue;  // E = 10 kPa, ν = 0.45
  tissue.validate();
  // λ = Eν/((1+ν)(1−2ν)) = 4500/0.145, μ = E/(2(1+ν)) = 10000/2.9.
  EXPECT_NEAR(tissue.lame_lambda_Pa(), 4500.0 / 0.145, 1e-9);
  EXPECT_NEAR(tissue.shear_modulus_Pa(), 10000.0 / 2.9, 1e-9);
  // E = μ(3λ + 2μ)/(λ + μ) and ν = λ/(2(λ + μ)) recover the inputs.
  const double lambda = tissue.lame_lambda_Pa(), mu = tissue.shear_modulus_Pa();
  EXPECT_NEAR(mu * (3 * lambda + 2 * mu) / (lambda + mu), tissue.youngs_modulus_Pa, 1e-9);
  EXPECT_NEAR(lambda / (2 * (lambda + mu)), tissue.poisson_ratio, 1e-15);
  EXPECT_EQ((Material{1.0, 0.0}).lame_lambda_Pa(), 0.0);
}

TEST(Material, ValidationNamesTheFieldAndValue) {
  expect_invalid_argument([] { Material{-1.0, 0.3}.validate(); }, {"Material.youngs_modulus_Pa", "-1", "> 0"});
  expect_invalid_argument([] { Material{0.0, 0.3}.validate(); }, {"Material.youngs_modulus_Pa", "0"});
  expect_invalid_argument([] { Material{std::numeric_limits<double>::infinity(), 0.3}.validate(); },
                          {"Material.youngs_modulus_Pa", "inf", "finite"});
  // Positive but far outside the solids: refused by name rather than left to overflow in a solver.
  expect_invalid_argument([] { Material{1e200, 0.3}.validate(); }, {"Material.youngs_modulus_Pa", "1e+200", "[1e-06, 1e+15] Pa"});
  expect_invalid_argument([] { Material{1e-300, 0.3}.validate(); }, {"Material.youngs_modulus_Pa", "1e-300", "[1e-06, 1e+15] Pa"});
  Material{min_youngs_modulus_Pa, 0.3}.validate();
  Material{max_youngs_modulus_Pa, 0.3}.validate();
  expect_invalid_argument([] { Material{1e4, 0.5}.validate(); }, {"Material.poisson_ratio", "0.5", "[0, 0.5)"});
  expect_invalid_argument([] { Material{1e4, -0.1}.validate(); }, {"Material.poisson_ratio", "-0.1"});
  expect_invalid_argument([] { Material{1e4, std::nan("")}.validate(); }, {"Material.poisson_ratio", "nan"});
  Material{1e4, 0.4999}.validate();
}

TEST(ContactCondition, NamesRoundTripAndUnknownNamesAreListed) {
  for (const ContactCondition condition : {ContactCondition::frictionless, ContactCondition::bonded}) {
    EXPECT_EQ(contact_condition_from_string(to_string(condition)), condition);
  }
  EXPECT_EQ(to_string(ContactCondition::frictionless), "frictionless");
  EXPECT_EQ(to_string(ContactCondition::bonded), "bonded");
  expect_invalid_argument([] { contact_condition_from_string("sticky"); }, {"'sticky'", "frictionless, bonded"});
}

}  // namespace
}  // namespace touchstone::geometry
