// source.ramp: exact values before, during and after the ramp, and configuration errors.
#include "ramp.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "source_tunable_checks.hpp"

namespace {

using lode::testing::BlockHarness;
using namespace lode::plugins::source::testing;  // the family's checks of runtime parameters

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

// ---- Runtime parameters (lode set) ----

TEST(SourceRampTunables, OffsetAndRatePerElement) {
  BlockHarness h("source.ramp", "names: [x, theta_z]\nunits: [m, rad]\nrate: [1e-3, 2e-3]\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  expect_tunables(h.tunables(),
                  {{"offset.x", "m"}, {"offset.theta_z", "rad"}, {"rate.x", "m/s"}, {"rate.theta_z", "rad/s"}});
  EXPECT_DOUBLE_EQ(h.tunables().tunable_value(3), 2e-3);
}

TEST(SourceRampTunables, NewRateBendsTheRampWithoutAJump) {
  BlockHarness h("source.ramp", "names: [x]\nunits: [m]\nrate: [1e-3]\nduration_s: 0.3\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  run_to(h, 99);
  EXPECT_NEAR(h.output("out")[0], 99e-6, 1e-18);
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(1, -2e-3, why)) << why;  // rate.x
  h.step();  // cycle 100: continues from 99 um with the new slope
  EXPECT_NEAR(h.output("out")[0], 99e-6 - 2e-6, 1e-18);
  run_to(h, 200);
  EXPECT_NEAR(h.output("out")[0], 99e-6 - 2e-3 * 0.101, 1e-18);
  run_to(h, 500);  // held after duration_s = 0.3 at the bent ramp's value
  EXPECT_NEAR(h.output("out")[0], 99e-6 - 2e-3 * 0.201, 1e-18);
  EXPECT_NEAR(h.describe().find("final_value")->elements().at(0).as_number(), 99e-6 - 2e-3 * 0.201, 1e-18);
  // A new offset shifts the whole path from the next sample.
  ASSERT_TRUE(h.tunables().set_tunable(0, 1e-3, why)) << why;
  h.step();
  EXPECT_NEAR(h.output("out")[0], 1e-3 + 99e-6 - 2e-3 * 0.201, 1e-18);
}

TEST(SourceRampTunables, RefusedValuesChangeNothing) {
  expect_refusals_change_nothing("source.ramp", "names: [x]\nunits: [m]\nrate: [1e-3]\n", 1000.0, [](lode::Tunables& b) {
    const char* why = "";
    EXPECT_FALSE(b.set_tunable(1, std::numeric_limits<double>::infinity(), why));
    EXPECT_STRNE(why, "");
    EXPECT_FALSE(b.set_tunable(2, 1.0, why));
    EXPECT_DOUBLE_EQ(b.tunable_value(1), 1e-3);
  });
}

TEST(SourceRampTunables, SetTunableAllocatesNothing) {
  BlockHarness h("source.ramp", "names: [x]\nunits: [m]\nrate: [1e-3]\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  expect_set_tunable_allocates_nothing(h, 1, 1e-3, -1e-3);
}

}  // namespace
