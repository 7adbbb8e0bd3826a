#pragma once
// Bad input must fail with a message that names what is wrong.

#include <gtest/gtest.h>

#include <exception>
#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace touchstone::testing {

/// Runs `action`, expects std::invalid_argument whose message contains every fragment.
inline void expect_invalid_argument(const std::function<void()>& action, std::initializer_list<std::string> fragments) {
  try {
    action();
    ADD_FAILURE() << "no exception; expected one mentioning '" << *fragments.begin() << "'";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    for (const std::string& fragment : fragments) {
      EXPECT_NE(message.find(fragment), std::string::npos) << "'" << fragment << "' missing from: " << message;
    }
  } catch (const std::exception& error) {
    ADD_FAILURE() << "wrong exception type: " << error.what();
  }
}

}  // namespace touchstone::testing
