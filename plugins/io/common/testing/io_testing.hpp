// Helpers for the io plugins' tests.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "lode/sdk/port.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins::boards::testing {

/// What `plugin` reports when it refuses `params` at `rate_hz`, its command input fed with
/// `command` first (when not empty). Configuring successfully fails the calling test.
inline std::string refusal_of(const std::string& plugin, const std::string& params, double rate_hz,
                              const Elements& command = {}) {
  lode::testing::BlockHarness h(plugin, params, rate_hz);
  if (!command.empty()) h.feed("command", command);
  EXPECT_FALSE(h.configure()) << plugin << " accepted:\n" << params;
  return h.diagnostics();
}

}  // namespace lode::plugins::boards::testing
