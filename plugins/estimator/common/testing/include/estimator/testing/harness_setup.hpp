// Starting an estimator under the test harness, a faulting input that must leave it as it was,
// and counting what a run allocates: the set-up and the real-time checks every estimator
// plugin's tests repeat.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <vector>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::estimator_testing {

/// configure() then activate() (inputs fed before), for ASSERT_TRUE(started(h)): a failure
/// says which one failed, with the diagnostics of configure().
inline ::testing::AssertionResult started(lode::testing::BlockHarness& h) {
  if (!h.configure()) return ::testing::AssertionFailure() << "configure() failed: " << h.diagnostics();
  if (!h.activate()) return ::testing::AssertionFailure() << "activate() failed";
  return ::testing::AssertionSuccess();
}

/// One non-finite input element (input `input`, element `element` set to `value`) makes step()
/// fault with exactly `reason` and leaves output `output` as it was: the block checks its
/// inputs before it changes anything.
inline ::testing::AssertionResult faults_and_holds(lode::testing::BlockHarness& h, const std::string& input,
                                                   std::size_t element, double value, const std::string& reason,
                                                   const std::string& output) {
  const auto held = h.output(output);
  const std::vector<double> before(held.begin(), held.end());
  h.input(input)[element] = value;
  if (h.step() != StepStatus::fault) {
    return ::testing::AssertionFailure() << input << "[" << element << "] = " << value << " did not fault";
  }
  if (reason != h.block().fault_reason()) {
    return ::testing::AssertionFailure() << "fault reason '" << h.block().fault_reason() << "', expected '" << reason
                                         << "'";
  }
  const auto after = h.output(output);
  if (!std::equal(before.begin(), before.end(), after.begin(), after.end())) {
    return ::testing::AssertionFailure() << "output '" << output << "' changed on the faulting step";
  }
  return ::testing::AssertionSuccess();
}

/// The two blocks' outputs `ports` hold exactly the same values after cycle `cycle`, for
/// ASSERT_TRUE: a failure names the first element that differs and by how much (a compile-time
/// sized kernel against the general one must agree bit for bit).
inline ::testing::AssertionResult same_outputs(lode::testing::BlockHarness& a, lode::testing::BlockHarness& b,
                                               std::initializer_list<const char*> ports, std::size_t cycle) {
  for (const char* port : ports) {
    const auto x = a.output(port);
    const auto y = b.output(port);
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (x[i] != y[i]) {
        return ::testing::AssertionFailure() << port << "[" << i << "] at cycle " << cycle << " differs by "
                                             << x[i] - y[i];
      }
    }
  }
  return ::testing::AssertionSuccess();
}

/// The heap allocations made while `run()` runs (LODE_REQUIRE_ALLOCATION_COUNTING() first).
template <typename Run>
std::size_t allocations_during(Run&& run) {
  const std::size_t before = lode::testing::allocation_count();
  run();
  return lode::testing::allocation_count() - before;
}

}  // namespace lode::estimator_testing
