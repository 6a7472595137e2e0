#pragma once
// Test helper of ropes_eval's unit tests: `call` must throw std::invalid_argument whose
// message contains `needle`.
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>

namespace ropes::eval::test_support {

inline void expect_message(const std::function<void()>& call, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected one containing '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace ropes::eval::test_support
