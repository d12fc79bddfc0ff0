// source.sine: exact values at chosen times against the closed form, and configuration errors.
#include "sine.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "source_tunable_checks.hpp"

namespace {

using lode::testing::BlockHarness;
using namespace lode::plugins::source::testing;  // the family's checks of runtime parameters

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

// ---- Runtime parameters (lode set) ----

TEST(SourceSineTunables, OffsetAmplitudeAndFrequencyUpToNyquist) {
  BlockHarness h("source.sine", "names: [x]\nunits: [m]\namplitude: [1e-4]\nfrequency_hz: [10]\n", kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  expect_tunables(h.tunables(), {{"offset.x", "m"}, {"amplitude.x", "m"}, {"frequency_hz.x", "Hz"}});
  const auto t = h.tunables().tunables();
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[2].min, 0.0);
  EXPECT_EQ(t[2].max, 500.0);
  EXPECT_DOUBLE_EQ(h.tunables().tunable_value(2), 10.0);
}

TEST(SourceSineTunables, NewFrequencyKeepsThePhaseOfTheLastSample) {
  BlockHarness h("source.sine", "names: [u]\nunits: [N]\namplitude: [1]\nfrequency_hz: [10]\n", kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  while (h.tick().cycle < 123) h.step();
  // 10 Hz for 0.123 s: 1.23 cycles.
  EXPECT_NEAR(h.output("out")[0], std::sin(2 * std::numbers::pi * 0.23), 1e-12);
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(2, 25.0, why)) << why;
  h.step();  // one ms at 25 Hz from phase 0.23 cycles (not sin(2 pi 25 * 0.124): no phase jump)
  EXPECT_NEAR(h.output("out")[0], std::sin(2 * std::numbers::pi * (0.23 + 0.025)), 1e-12);
  while (h.tick().cycle < 200) h.step();
  EXPECT_NEAR(h.output("out")[0], std::sin(2 * std::numbers::pi * (0.23 + 25 * 0.077)), 1e-12);
  // Amplitude and offset: the next sample is the new offset + new amplitude * sin(phase).
  ASSERT_TRUE(h.tunables().set_tunable(1, 3.0, why)) << why;
  ASSERT_TRUE(h.tunables().set_tunable(0, -0.5, why)) << why;
  h.step();
  EXPECT_NEAR(h.output("out")[0], -0.5 + 3.0 * std::sin(2 * std::numbers::pi * (0.23 + 25 * 0.078)), 1e-12);
}

TEST(SourceSineTunables, RefusedValuesChangeNothing) {
  const char* params = "names: [u]\nunits: [N]\namplitude: [1]\nfrequency_hz: [10]\n";
  expect_refusals_change_nothing("source.sine", params, kRateHz, [](lode::Tunables& b) {
    const char* why = "";
    EXPECT_FALSE(b.set_tunable(2, 600.0, why)) << "above Nyquist (500 Hz)";
    EXPECT_NE(std::string(why).find("Nyquist"), std::string::npos) << why;
    EXPECT_FALSE(b.set_tunable(2, -1.0, why));
    EXPECT_FALSE(b.set_tunable(1, std::nan(""), why));
    EXPECT_FALSE(b.set_tunable(3, 1.0, why));
    EXPECT_DOUBLE_EQ(b.tunable_value(2), 10.0);
  });
}

TEST(SourceSineTunables, SetTunableAllocatesNothing) {
  BlockHarness h("source.sine", "names: [u]\nunits: [N]\namplitude: [1]\nfrequency_hz: [10]\n", kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  expect_set_tunable_allocates_nothing(h, 2, 20.0, 30.0);
}

}  // namespace
