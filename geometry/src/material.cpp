// Validation and names of the parameter types the two models share.
#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/geometry/material.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace touchstone::geometry {
namespace {

[[noreturn]] void reject(const std::string& field, double value, const std::string& rule) {
  std::ostringstream message;
  message << field << " = " << value << " " << rule;
  throw std::invalid_argument(message.str());
}

}  // namespace

void Material::validate() const {
  if (!std::isfinite(youngs_modulus_Pa) || youngs_modulus_Pa <= 0)
    reject("Material.youngs_modulus_Pa", youngs_modulus_Pa, "must be finite and > 0");
  if (!std::isfinite(poisson_ratio) || poisson_ratio < 0 || poisson_ratio >= 0.5)
    reject("Material.poisson_ratio", poisson_ratio, "must be in [0, 0.5)");
}

std::string to_string(ContactCondition condition) {
  return condition == ContactCondition::bonded ? "bonded" : "frictionless";
}

ContactCondition contact_condition_from_string(const std::string& name) {
  if (name == "bonded") return ContactCondition::bonded;
  if (name == "frictionless") return ContactCondition::frictionless;
  throw std::invalid_argument("unknown contact '" + name + "' (choose frictionless, bonded)");
}

}  // namespace touchstone::geometry
