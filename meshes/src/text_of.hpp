#pragma once
// Internal to touchstone::meshes: numbers in error messages.

#include <sstream>
#include <string>

namespace touchstone::meshes::internal {

/// A number as an output stream prints it (six significant digits), for messages.
inline std::string text_of(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

}  // namespace touchstone::meshes::internal
