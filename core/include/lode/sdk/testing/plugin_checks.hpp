// Checks that plugin tests share (GoogleTest): reading describe()'s JSON, where a missing key
// is a test failure that names the key instead of a crash, and a configuration that must be
// refused with a given message.
//
//   const Json d = h.describe();
//   const std::vector<double> b = numbers_of(member(member(d, "channels").elements().at(0), "b"));
//   EXPECT_TRUE(configure_fails_with(h, "below Nyquist"));
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/json.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::testing {

/// object[key]; a missing key fails the test and gives a null Json.
inline const Json& member(const Json& object, const std::string& key) {
  const Json* m = object.find(key);
  if (m == nullptr) {
    static const Json null;
    ADD_FAILURE() << "describe() has no '" << key << "'";
    return null;
  }
  return *m;
}

/// The numbers of a JSON array.
inline std::vector<double> numbers_of(const Json& array) {
  std::vector<double> out;
  for (const Json& e : array.elements()) out.push_back(e.as_number());
  return out;
}

/// configure() refuses the block's parameters and its diagnostics contain `fragment`.
inline ::testing::AssertionResult configure_fails_with(BlockHarness& h, std::string_view fragment) {
  if (h.configure()) return ::testing::AssertionFailure() << "configure() succeeded";
  const std::string diagnostics = h.diagnostics();
  if (diagnostics.find(fragment) == std::string::npos) {
    return ::testing::AssertionFailure() << "expected '" << fragment << "' in:\n" << diagnostics;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace lode::testing
