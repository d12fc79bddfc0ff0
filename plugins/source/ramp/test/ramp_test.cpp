// source.ramp: exact values before, during and after the ramp, and configuration errors.
#include "ramp.hpp"

#include <gtest/gtest.h>

#include <string>

#include "lode/testing/harness.hpp"

namespace {

using lode::testing::BlockHarness;

constexpr double kRateHz = 1000.0;  // tick k at exactly k ms

void run_to(BlockHarness& h, std::uint64_t cycle) {
  while (h.tick().cycle < cycle) h.step();
}

TEST(SourceRamp, RampsBetweenStartAndDurationThenHolds) {
  BlockHarness h("source.ramp", R"(
names: [theta_z, x]
units: [rad, m]
offset: [0.01, -2e-3]
rate: [0.02, 1e-3]
start_s: 0.1
duration_s: 0.5)",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  EXPECT_EQ(h.output_elements("out")[0].unit, "rad");
  h.step();
  struct Expect {
    std::uint64_t ms;
    double ramp_s;  // time spent ramping
  };
  const Expect expected[] = {{0, 0.0},   {50, 0.0},   {100, 0.0}, {101, 0.001},
                             {350, 0.25}, {599, 0.499}, {600, 0.5}, {2000, 0.5}};
  for (const auto& e : expected) {
    run_to(h, e.ms);
    EXPECT_NEAR(h.output("out")[0], 0.01 + 0.02 * e.ramp_s, 1e-17) << e.ms << " ms";
    EXPECT_NEAR(h.output("out")[1], -2e-3 + 1e-3 * e.ramp_s, 1e-18) << e.ms << " ms";
  }
  EXPECT_EQ(h.output("out")[0], 0.01 + 0.02 * 0.5) << "the hold is exact";
}

TEST(SourceRamp, WithoutDurationItNeverStops) {
  BlockHarness h("source.ramp", "names: [y]\nunits: [m]\nrate: [0.05]\n", kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  EXPECT_EQ(h.output("out")[0], 0.0);
  run_to(h, 3000);
  EXPECT_NEAR(h.output("out")[0], 0.15, 1e-15);
  run_to(h, 10000);
  EXPECT_NEAR(h.output("out")[0], 0.5, 1e-15);
}

TEST(SourceRamp, ConfigurationErrorsAreLocated) {
  BlockHarness h("source.ramp", R"(
names: [x, y]
units: [m, m]
rate: [1]
start_s: -0.5
duration_s: -1)",
                 kRateHz);
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* expected : {"blocks.dut.rate: expected 2 numbers, got 1",
                               "blocks.dut.start_s: must be within [0, 1e9] s, got -0.5",
                               "blocks.dut.duration_s: must be within [0, 1e9] s, got -1"}) {
    EXPECT_NE(d.find(expected), std::string::npos) << "missing: " << expected << "\n" << d;
  }
  BlockHarness missing("source.ramp", "names: [x]\nunits: [m]\n", kRateHz);
  EXPECT_FALSE(missing.configure());
  EXPECT_NE(missing.diagnostics().find("blocks.dut.rate: missing required parameter"),
            std::string::npos)
      << missing.diagnostics();
}

TEST(SourceRamp, DescribeGivesTheFinalValue) {
  BlockHarness h("source.ramp", "names: [x]\nunits: [m]\noffset: [1]\nrate: [2]\nduration_s: 3\n",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const lode::Json d = h.describe();
  ASSERT_NE(d.find("final_value"), nullptr);
  EXPECT_EQ(d.find("final_value")->elements()[0].as_number(), 7.0);
}

}  // namespace
