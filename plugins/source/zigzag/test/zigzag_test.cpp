// source.zigzag: exact path values at the turning points and in between, both advance modes,
// the cycle limit and hold, continuity, and configuration errors.
#include "zigzag.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "source_tunable_checks.hpp"

namespace {

using lode::testing::BlockHarness;
using namespace lode::plugins::source::testing;  // the family's checks of runtime parameters

constexpr double kRateHz = 1000.0;  // tick k at exactly k ms

// X sweeps 10 mm out and back every second while Y advances 1 mm per half period.
const std::string kPath = R"(
names: [x, y]
units: [m, m]
offset: [-5e-3, 2e-3]
amplitude: [10e-3, 0]
advance: [0, 1e-3]
period_s: 1
cycles: 2
start_s: 0.5
)";

struct Point {
  std::uint64_t ms;
  double x, y;  // relative to offset
};

void expect_path(const std::string& params, std::initializer_list<Point> points) {
  BlockHarness h("source.zigzag", params, kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  for (const Point& p : points) {
    while (h.tick().cycle < p.ms) h.step();
    EXPECT_NEAR(h.output("out")[0], -5e-3 + p.x, 1e-17) << p.ms << " ms";
    EXPECT_NEAR(h.output("out")[1], 2e-3 + p.y, 1e-17) << p.ms << " ms";
  }
}

TEST(SourceZigzag, RampModeAdvancesWhileSweeping) {
  expect_path(kPath, {{0, 0, 0},
                      {500, 0, 0},               // start
                      {750, 5e-3, 0.5e-3},       // half way out
                      {1000, 10e-3, 1e-3},       // first turning point
                      {1250, 5e-3, 1.5e-3},      // half way back
                      {1500, 0, 2e-3},           // second turning point
                      {2000, 10e-3, 3e-3},
                      {2500, 0, 4e-3},           // end of cycle 2
                      {2501, 0, 4e-3},           // hold
                      {9000, 0, 4e-3}});
}

TEST(SourceZigzag, StepModeAddsTheIncrementAtTurningPoints) {
  expect_path(kPath + "advance_mode: step\n", {{750, 5e-3, 0},
                                               {999, 9.98e-3, 0},
                                               {1000, 10e-3, 1e-3},
                                               {1250, 5e-3, 1e-3},
                                               {1499, 0.02e-3, 1e-3},
                                               {1500, 0, 2e-3},
                                               {2499, 0.02e-3, 3e-3},
                                               {2500, 0, 4e-3},
                                               {5000, 0, 4e-3}});
}

TEST(SourceZigzag, RampModePathIsContinuous) {
  BlockHarness h("source.zigzag", kPath, kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  double previous_x = h.output("out")[0], previous_y = h.output("out")[1];
  double largest_x = 0.0, largest_y = 0.0;
  for (int k = 1; k < 3000; ++k) {
    h.step();
    largest_x = std::max(largest_x, std::abs(h.output("out")[0] - previous_x));
    largest_y = std::max(largest_y, std::abs(h.output("out")[1] - previous_y));
    previous_x = h.output("out")[0];
    previous_y = h.output("out")[1];
  }
  // Speeds: x 20 mm/s, y 2 mm/s -> 20 um and 2 um per 1 ms cycle at most.
  EXPECT_NEAR(largest_x, 20e-6, 1e-15);
  EXPECT_NEAR(largest_y, 2e-6, 1e-15);
}

TEST(SourceZigzag, RunsForeverWithoutCycles) {
  BlockHarness h("source.zigzag",
                 "names: [x]\nunits: [m]\namplitude: [1]\nadvance: [0.5]\nperiod_s: 0.2\n", kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  while (h.tick().cycle < 10000) h.step();  // 50 periods = 100 half periods
  EXPECT_NEAR(h.output("out")[0], 100 * 0.5, 1e-12);
  while (h.tick().cycle < 10050) h.step();  // a quarter period later: half way out
  EXPECT_NEAR(h.output("out")[0], 1.0 * 0.5 + 100.5 * 0.5, 1e-12);
}

TEST(SourceZigzag, ConfigurationErrorsAreLocated) {
  BlockHarness h("source.zigzag", R"(
names: [x, y]
units: [m, m]
amplitude: [1]
period_s: 0
cycles: 0
advance_mode: diagonal)",
                 kRateHz);
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* expected : {"blocks.dut.amplitude: expected 2 numbers, got 1",
                               "blocks.dut.period_s: must be within (0, 1e9] s, got 0",
                               "blocks.dut.cycles: must be >= 1", "blocks.dut.advance_mode: 'diagonal' is not one of: ramp, step"}) {
    EXPECT_NE(d.find(expected), std::string::npos) << "missing: " << expected << "\n" << d;
  }
}

TEST(SourceZigzag, DescribeGivesTheEnd) {
  BlockHarness h("source.zigzag", kPath, kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const lode::Json d = h.describe();
  EXPECT_EQ(d.find("end_s")->as_number(), 2.5);
  EXPECT_NEAR(d.find("final_value")->elements()[1].as_number(), 2e-3 + 4e-3, 1e-18);
}

// ---- Runtime parameters (lode set) ----

TEST(SourceZigzagTunables, OffsetAndAmplitudePerElement) {
  BlockHarness h("source.zigzag", "names: [x, y]\nunits: [m, m]\namplitude: [1e-3, 0]\nadvance: [0, 1e-4]\n"
                                  "period_s: 1\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  expect_tunables(h.tunables(), {{"offset.x", "m"}, {"offset.y", "m"}, {"amplitude.x", "m"}, {"amplitude.y", "m"}});
  EXPECT_DOUBLE_EQ(h.tunables().tunable_value(2), 1e-3);
}

TEST(SourceZigzagTunables, NewAmplitudeAndOffsetApplyFromTheNextSample) {
  BlockHarness h("source.zigzag", "names: [x, y]\nunits: [m, m]\namplitude: [1e-3, 0]\nadvance: [0, 1e-4]\n"
                                  "period_s: 1\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  while (h.tick().cycle < 250) h.step();
  EXPECT_NEAR(h.output("out")[0], 0.5e-3, 1e-15);  // half way up the first sweep
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(2, 2e-3, why)) << why;
  h.step();
  EXPECT_NEAR(h.output("out")[0], 2e-3 * 0.502, 1e-15);
  ASSERT_TRUE(h.tunables().set_tunable(1, 5e-3, why)) << why;  // offset.y
  h.step();
  EXPECT_NEAR(h.output("out")[1], 5e-3 + 1e-4 * 0.504, 1e-15);
  EXPECT_FALSE(h.tunables().set_tunable(0, std::nan(""), why));
  EXPECT_STRNE(why, "");
  EXPECT_FALSE(h.tunables().set_tunable(4, 0.0, why));
  h.step();
  EXPECT_NEAR(h.output("out")[0], 2e-3 * 0.506, 1e-15) << "refused values changed nothing";
  EXPECT_DOUBLE_EQ(h.tunables().tunable_value(0), 0.0);
}

TEST(SourceZigzagTunables, SetTunableAllocatesNothing) {
  BlockHarness h("source.zigzag", "names: [x]\nunits: [m]\namplitude: [1e-3]\nperiod_s: 1\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  expect_set_tunable_allocates_nothing(h, 1, 1e-3, 2e-3);
}

}  // namespace
