// source.sine: exact values at chosen times against the closed form, and configuration errors.
#include "sine.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "lode/testing/harness.hpp"

namespace {

using lode::testing::BlockHarness;

constexpr double kRateHz = 1000.0;  // tick k at exactly k ms

TEST(SourceSine, MatchesClosedFormAfterStartAndOffsetBefore) {
  BlockHarness h("source.sine", R"(
names: [x, y]
units: [m, m]
offset: [1e-3, -1e-3]
amplitude: [1e-4, 2e-4]
frequency_hz: [2.5, 10]
phase_rad: [0, 1.5707963267948966]
start_s: 0.2)",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  for (std::uint64_t ms : {0u, 199u, 200u, 250u, 300u, 333u, 1000u, 1234u, 60000u}) {
    while (h.tick().cycle < ms) h.step();
    const double tau = (static_cast<double>(ms) - 200.0) * 1e-3;
    double x = 1e-3, y = -1e-3;
    if (tau >= 0) {
      x += 1e-4 * std::sin(2 * std::numbers::pi * 2.5 * tau);
      y += 2e-4 * std::sin(2 * std::numbers::pi * 10 * tau + std::numbers::pi / 2);
    }
    EXPECT_NEAR(h.output("out")[0], x, 1e-16) << ms << " ms";
    EXPECT_NEAR(h.output("out")[1], y, 1e-16) << ms << " ms";
  }
}

TEST(SourceSine, KnownPointsOfTheWave) {
  // 1 Hz, amplitude 2: peak at 0.25 s, zero at 0.5 s, trough at 0.75 s.
  BlockHarness h("source.sine", "names: [u]\nunits: [N]\namplitude: [2]\nfrequency_hz: [1]\n",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  EXPECT_EQ(h.output("out")[0], 0.0);
  while (h.tick().cycle < 250) h.step();
  EXPECT_NEAR(h.output("out")[0], 2.0, 1e-15);
  while (h.tick().cycle < 500) h.step();
  EXPECT_NEAR(h.output("out")[0], 0.0, 1e-15);
  while (h.tick().cycle < 750) h.step();
  EXPECT_NEAR(h.output("out")[0], -2.0, 1e-15);
}

TEST(SourceSine, ConfigurationErrorsAreLocated) {
  BlockHarness h("source.sine", R"(
names: [x, y]
units: [m, m]
amplitude: [1, 1]
frequency_hz: [-1, 600]
phase_rad: [0])",
                 kRateHz);
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* expected :
       {"blocks.dut.frequency_hz: must be >= 0 Hz, got -1 for element 0",
        "blocks.dut.frequency_hz: must not exceed the Nyquist frequency 500 Hz of this 1000 Hz "
        "block, got 600",
        "blocks.dut.phase_rad: expected 2 numbers, got 1"}) {
    EXPECT_NE(d.find(expected), std::string::npos) << "missing: " << expected << "\n" << d;
  }
}

}  // namespace
