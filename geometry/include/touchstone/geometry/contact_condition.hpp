#pragma once
/// @file
/// How a rigid flat tool face holds the tissue surface it presses: one definition for the
/// real-time model's tool patch and the finite element reference's punch.

#include <cstdint>
#include <string>

namespace touchstone::geometry {

/// With d the unit push direction and U the tool displacement:
enum class ContactCondition : std::uint8_t {
  frictionless,  ///< u·d = U·d on the face, tangential traction zero (the surface slides)
  bonded,        ///< u = U on the face, all three components (no slip)
};

/// "frictionless", "bonded".
std::string to_string(ContactCondition condition);
/// The to_string names; throws std::invalid_argument naming the value and the choices.
ContactCondition contact_condition_from_string(const std::string& name);

}  // namespace touchstone::geometry
