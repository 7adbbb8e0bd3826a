// Validation and names of the parameter types the two models share.
#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/geometry/invalid_value.hpp"
#include "touchstone/geometry/material.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace touchstone::geometry {
void Material::validate() const {
  if (!std::isfinite(youngs_modulus_Pa) || youngs_modulus_Pa <= 0)
    throw_invalid_value("Material.youngs_modulus_Pa", youngs_modulus_Pa, "must be finite and > 0");
  // The models are linear in E, but their factorisations multiply stiffness entries together:
  // far outside the range of solids (soft gels to diamond) they over- or underflow and end in a
  // status that blames the system rather than E.
  if (youngs_modulus_Pa < min_youngs_modulus_Pa || youngs_modulus_Pa > max_youngs_modulus_Pa) {
    std::ostringstream range;
    range << "Pa is outside [" << min_youngs_modulus_Pa << ", " << max_youngs_modulus_Pa
          << "] Pa, the range of solids with wide margins (soft gels to diamond)";
    throw_invalid_value("Material.youngs_modulus_Pa", youngs_modulus_Pa, range.str());
  }
  if (!std::isfinite(poisson_ratio) || poisson_ratio < 0 || poisson_ratio >= 0.5)
    throw_invalid_value("Material.poisson_ratio", poisson_ratio, "must be in [0, 0.5)");
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
