// Helpers for the tests of the model plugins (plants, and the sensors whose tests run a plant).
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <initializer_list>
#include <string>
#include <string_view>

#include "lode/sdk/port.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins::plants::testing {

/// The plant's full state (PlantModel::state()) as an array of its kStateSize.
template <typename Plant>
std::array<double, Plant::kStateSize> state_of(const Plant& plant) {
  std::array<double, Plant::kStateSize> x{};
  plant.state(x.data());
  return x;
}

/// "fx [N], fy [N], tz [N*m]": names and units in order, to compare a whole port at once.
inline std::string element_list(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out;
}

/// configure() refuses the harness (e.g. io.sim with a badly parameterised model) and its
/// diagnostics contain every fragment: one run reports every problem, each at its own key.
inline ::testing::AssertionResult configure_refused_naming(lode::testing::BlockHarness& h,
                                                          std::initializer_list<std::string_view> fragments) {
  if (h.configure()) return ::testing::AssertionFailure() << "configure() succeeded";
  const std::string diagnostics = h.diagnostics();
  std::string missing;
  for (std::string_view fragment : fragments) {
    if (diagnostics.find(fragment) == std::string::npos) missing += "\n  '" + std::string(fragment) + "'";
  }
  if (!missing.empty()) return ::testing::AssertionFailure() << "not reported:" << missing << "\nin:\n" << diagnostics;
  return ::testing::AssertionSuccess();
}

}  // namespace lode::plugins::plants::testing
