// Hot swap between two instances of an estimator, as the tests of every estimator with a state
// check it: the newcomer takes over the incumbent's exported state and from then on must give
// the very same outputs (no transient, bit for bit).
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"

namespace lode::estimator_testing {

/// `to` imports the state `from` exports, every element present; it must then export exactly
/// that state (values and covariance).
inline ::testing::AssertionResult hand_over(EstimatorState& from, EstimatorState& to) {
  const lode::testing::ExportedState e = lode::testing::export_state_of(from);
  const std::vector<std::uint8_t> present(e.values.size(), 1);
  to.import_state(e.values.data(), e.covariance.data(), present.data());
  const lode::testing::ExportedState got = lode::testing::export_state_of(to);
  if (got.values != e.values) return ::testing::AssertionFailure() << "the imported state is exported otherwise";
  if (from.state_layout().covariance && got.covariance != e.covariance) {
    return ::testing::AssertionFailure() << "the imported covariance is exported otherwise";
  }
  return ::testing::AssertionSuccess();
}

/// Every element of the outputs `ports` is the same, bit for bit, in `a` and `b`.
inline ::testing::AssertionResult same_outputs(const lode::testing::BlockHarness& a,
                                               const lode::testing::BlockHarness& b,
                                               const std::vector<std::string>& ports) {
  for (const std::string& port : ports) {
    const auto x = a.output(port);
    const auto y = b.output(port);
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!(x[i] == y[i])) {
        return ::testing::AssertionFailure() << port << "[" << i << "]: " << x[i] << " and " << y[i];
      }
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace lode::estimator_testing
