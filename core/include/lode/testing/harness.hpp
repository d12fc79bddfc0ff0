// Drive one block through the same port API the scheduler uses, for plugin unit tests: the
// tests' name for lode::BlockHost (lode/sdk/testing/block_host.hpp), which has the whole interface.
//
//   lode::testing::BlockHarness h("estimator.kalman", R"(
//       motion: constant_acceleration
//       q: [100, 100, 1e5])", 800.0);
//   h.feed("input", {{"x","m"},{"y","m"},{"theta_z","rad"}});   // a test source
//   ASSERT_TRUE(h.configure()) << h.diagnostics();
//   ASSERT_TRUE(h.activate());
//   h.input("input")[0] = 1e-4;  h.step();
//   double x = h.output("pose")[0];
#pragma once

#include "lode/sdk/testing/block_host.hpp"

namespace lode::testing {

using BlockHarness = BlockHost;

}  // namespace lode::testing
