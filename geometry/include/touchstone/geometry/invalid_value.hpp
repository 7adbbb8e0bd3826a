#pragma once
/// @file
/// The one message form of every parameter struct's validate(): "<Struct.field> = <value> <rule>".

#include <sstream>
#include <stdexcept>
#include <string>

namespace touchstone::geometry {

/// Throws std::invalid_argument("<field> = <value> <rule>").
[[noreturn]] inline void throw_invalid_value(const std::string& field, double value, const std::string& rule) {
  std::ostringstream message;
  message << field << " = " << value << " " << rule;
  throw std::invalid_argument(message.str());
}

}  // namespace touchstone::geometry
