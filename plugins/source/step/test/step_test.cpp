// source.step: exact values at chosen scheduled times, and located configuration errors.
#include "step.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "source_tunable_checks.hpp"

namespace {

using lode::testing::BlockHarness;
using namespace lode::plugins::source::testing;  // the family's checks of runtime parameters

// 1 kHz: the harness's tick k is scheduled at exactly k ms.
constexpr double kRateHz = 1000.0;


TEST(SourceStep, PiecewiseConstantAtExactTimes) {
  BlockHarness h("source.step", R"(
names: [x, theta_z]
units: [m, rad]
offset: [5e-6, -1e-3]
steps:
  - {time_s: 0.1, value: [1e-4, 0]}
  - {time_s: 0.25, value: [2e-4, 1e-3]}
  - {time_s: 1, value: [0, 0]})",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto& elements = h.output_elements("out");
  ASSERT_EQ(elements.size(), 2u);
  EXPECT_EQ(elements[0].name, "x");
  EXPECT_EQ(elements[0].unit, "m");
  EXPECT_EQ(elements[1].name, "theta_z");
  EXPECT_EQ(elements[1].unit, "rad");
  EXPECT_EQ(h.output("out")[0], 5e-6) << "activate() writes the offset";

  struct Expect {
    std::uint64_t cycle;  // = ms
    double x, theta;
  };
  const Expect expected[] = {{0, 5e-6, -1e-3},   {99, 5e-6, -1e-3}, {100, 1e-4, 0.0},
                             {249, 1e-4, 0.0},   {250, 2e-4, 1e-3}, {999, 2e-4, 1e-3},
                             {1000, 0.0, 0.0},   {3000, 0.0, 0.0}};
  h.step();  // cycle 0
  for (const auto& e : expected) {
    while (h.tick().cycle < e.cycle) h.step();
    ASSERT_EQ(h.tick().time_ns, static_cast<std::int64_t>(e.cycle) * 1'000'000);
    EXPECT_EQ(h.output("out")[0], e.x) << "t = " << e.cycle << " ms";
    EXPECT_EQ(h.output("out")[1], e.theta) << "t = " << e.cycle << " ms";
  }
}

TEST(SourceStep, AnyTickOrderGivesTheValueOfItsOwnTime) {
  // step() starts from the count of steps the last tick had reached; a tick before or after
  // it, by any amount, must still get the value of its own scheduled time.
  BlockHarness h("source.step", R"(
names: [x]
units: [m]
offset: [-1]
steps:
  - {time_s: 0.1, value: [1]}
  - {time_s: 0.25, value: [2]}
  - {time_s: 1, value: [3]})",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto expected = [](std::int64_t ms) { return ms < 100 ? -1.0 : ms < 250 ? 1.0 : ms < 1000 ? 2.0 : 3.0; };
  std::uint64_t state = 12345;
  for (int i = 0; i < 3000; ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    // Mostly neighbours of the step times, where a stale count is off by one.
    const std::int64_t ms = i % 2 == 0 ? static_cast<std::int64_t>((state >> 33) % 1500)
                                       : std::int64_t{100} * static_cast<std::int64_t>((state >> 33) % 11) +
                                             static_cast<std::int64_t>((state >> 20) % 3) - 1;
    lode::Tick t;
    t.cycle = static_cast<std::uint64_t>(std::max<std::int64_t>(ms, 0));
    t.time_ns = ms * 1'000'000;
    t.dt_s = 1.0 / kRateHz;
    ASSERT_EQ(h.block().step(t), lode::StepStatus::ok);
    ASSERT_EQ(h.output("out")[0], expected(ms)) << "t = " << ms << " ms, draw " << i;
  }
}

TEST(SourceStep, StepAtTimeZeroAppliesOnTheFirstCycle) {
  BlockHarness h("source.step", "names: [y]\nunits: [m]\nsteps: [{time_s: 0, value: [1e-5]}]\n",
                 800.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.step();
  EXPECT_EQ(h.output("out")[0], 1e-5);
}

// At 800 Hz the cycles are 1.25 ms apart: a step at 0.1 s lands exactly on cycle 80 (the
// thesis's "80th sample", Fig. 37), not one early or late through rounding.
TEST(SourceStep, ThesisStepLandsOnCycle80At800Hz) {
  BlockHarness h("source.step", "names: [x]\nunits: [m]\nsteps: [{time_s: 0.1, value: [1e-4]}]\n",
                 800.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  for (int k = 0; k < 80; ++k) {
    h.step();
    EXPECT_EQ(h.output("out")[0], 0.0) << "cycle " << h.tick().cycle;
  }
  h.step();
  EXPECT_EQ(h.tick().cycle, 80u);
  EXPECT_EQ(h.output("out")[0], 1e-4);
}

std::string configure_error(const std::string& params) {
  BlockHarness h("source.step", params, kRateHz);
  const lode::Status st = h.configure();
  return st ? std::string("(configured)") : h.diagnostics();
}

TEST(SourceStep, UnsortedStepsAreALocatedError) {
  const std::string d = configure_error(R"(
names: [x]
units: [m]
steps:
  - {time_s: 0.5, value: [1]}
  - {time_s: 0.2, value: [2]})");
  EXPECT_NE(d.find("blocks.dut.steps[1].time_s: steps must be sorted by strictly increasing "
                   "time_s; 0.2 s does not come after 0.5 s"),
            std::string::npos)
      << d;
}

TEST(SourceStep, ShapeErrorsAreAllReported) {
  const std::string d = configure_error(R"(
names: [x, y]
units: [m]
offset: [1, 2, 3]
steps:
  - {time_s: -1, value: [1, 2]}
  - {value: [1]})");
  for (const char* expected : {"blocks.dut.units: expected 2 units (one per name), got 1",
                               "blocks.dut.offset: expected 2 numbers, got 3",
                               "blocks.dut.steps[0].time_s: must be within [0, 1e9] s, got -1",
                               "blocks.dut.steps[1].time_s: missing required parameter",
                               "blocks.dut.steps[1].value: expected 2 numbers, got 1"}) {
    EXPECT_NE(d.find(expected), std::string::npos) << "missing: " << expected << "\n" << d;
  }
}

TEST(SourceStep, NamesUnitsAndStepsAreRequired) {
  const std::string d = configure_error("offset: [0]\n");
  EXPECT_NE(d.find("blocks.dut.names:"), std::string::npos) << d;
  EXPECT_NE(d.find("blocks.dut.units:"), std::string::npos) << d;
  EXPECT_NE(d.find("blocks.dut.steps: missing required parameter"), std::string::npos) << d;
  const std::string dup = configure_error("names: [x, x]\nunits: [m, m]\nsteps: [{time_s: 0, value: [1, 1]}]\n");
  EXPECT_NE(dup.find("duplicate element name 'x'"), std::string::npos) << dup;
}

TEST(SourceStep, DescribeListsTheSteps) {
  BlockHarness h("source.step", "names: [x]\nunits: [m]\nsteps: [{time_s: 0.5, value: [2]}]\n",
                 kRateHz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const lode::Json d = h.describe();
  ASSERT_NE(d.find("steps"), nullptr);
  ASSERT_EQ(d.find("steps")->elements().size(), 1u);
  EXPECT_EQ(d.find("steps")->elements()[0].find("time_s")->as_number(), 0.5);
}

// ---- Runtime parameters (lode set) ----

TEST(SourceStepTunables, OffsetPerElementWithItsUnit) {
  BlockHarness h("source.step", "names: [x, theta_z]\nunits: [m, rad]\noffset: [1e-3, 0]\n"
                                "steps: [{time_s: 0.5, value: [2e-3, 1e-3]}]\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  expect_tunables(h.tunables(), {{"offset.x", "m"}, {"offset.theta_z", "rad"}});
  const auto t = h.tunables().tunables();
  ASSERT_EQ(t.size(), 2u);
  EXPECT_FALSE(t[0].integer);
  EXPECT_LE(t[0].min, -1e300);
  EXPECT_GE(t[0].max, 1e300);
  EXPECT_DOUBLE_EQ(h.tunables().tunable_value(0), 1e-3);
}

TEST(SourceStepTunables, NewOffsetAppliesFromTheNextSampleAndRefusalsChangeNothing) {
  BlockHarness h("source.step", "names: [x, theta_z]\nunits: [m, rad]\noffset: [1e-3, 0]\n"
                                "steps: [{time_s: 0.5, value: [2e-3, 1e-3]}]\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  for (int k = 0; k < 10; ++k) h.step();
  EXPECT_EQ(h.output("out")[0], 1e-3);
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(0, -4e-3, why)) << why;
  EXPECT_EQ(h.output("out")[0], 1e-3) << "nothing changes before the next step";
  h.step();
  EXPECT_EQ(h.output("out")[0], -4e-3);
  EXPECT_EQ(h.output("out")[1], 0.0);
  EXPECT_FALSE(h.tunables().set_tunable(1, std::nan(""), why));
  EXPECT_STRNE(why, "");
  why = "";
  EXPECT_FALSE(h.tunables().set_tunable(2, 1.0, why));
  EXPECT_STRNE(why, "");
  h.step();
  EXPECT_EQ(h.output("out")[1], 0.0);
  EXPECT_EQ(h.tunables().tunable_value(1), 0.0);
  while (h.tick().cycle < 500) h.step();
  EXPECT_EQ(h.output("out")[0], 2e-3) << "the steps' absolute values are not offset";
}

TEST(SourceStepTunables, SetTunableAllocatesNothing) {
  BlockHarness h("source.step", "names: [x]\nunits: [m]\nsteps: [{time_s: 0.5, value: [2e-3]}]\n", 1000.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  expect_set_tunable_allocates_nothing(h, 0, 1e-3, -1e-3);
}

}  // namespace
