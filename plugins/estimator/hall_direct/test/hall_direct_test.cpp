// estimator.hall_direct: eq. 14-16 through the block (with and without the coil-voltage
// input), clamping and its counter, choosing the channel by name, configuration errors,
// faults and no allocation in step().
#include "hall_direct.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "estimator/testing/harness_setup.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

using lode::estimator_testing::started;

namespace hall = lode::plugins::hall;

double quiescent(double v) { return 1.299e-6 * v * v + 9.05e-5 * v + 2.544; }

TEST(HallDirect, ConvertsWithCoilCompensation) {
  lode::testing::BlockHarness h("estimator.hall_direct", "", 2000.0);
  h.feed("signals", {{"hall", "V"}});
  h.feed("coil_voltage", {{"gap", "m"}, {"coil_voltage", "V"}});  // like io.sim's truth
  ASSERT_TRUE(started(h));
  ASSERT_EQ(h.output_elements("gap")[0].name, "gap");
  ASSERT_EQ(h.output_elements("gap")[0].unit, "m");
  // Spec §1.3 table: C_H = 0.1, 0.2, ..., 0.8 V -> 33.69, 27.15, ..., 16.29 mm.
  const double expected_mm[] = {46.9, 33.69, 27.15, 23.61, 21.27, 19.55, 18.41, 17.65, 16.29};
  for (int k = 0; k <= 8; ++k) {
    const double c_h = 0.1 * k;
    const double v = 0.5 + 0.3 * k;
    h.input("signals")[0] = quiescent(v) + c_h;
    h.input("coil_voltage")[1] = v;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    EXPECT_NEAR(h.output("gap")[0], 1e-3 * expected_mm[k], 0.01e-3) << "C_H = " << c_h;
    EXPECT_NEAR(h.output("compensated")[0], c_h, 1e-12);
  }
  EXPECT_EQ(h.describe().find("coil_compensation")->as_string(), "coil_voltage input");
}

TEST(HallDirect, WithoutTheCoilInputOnlyTheQuiescentLevelIsRemoved) {
  lode::testing::BlockHarness h("estimator.hall_direct", "", 2000.0);
  h.feed("signals", {{"hall", "V"}});
  ASSERT_TRUE(started(h));
  h.input("signals")[0] = 2.544 + 0.2;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("gap")[0], 27.1525e-3, 1e-7);
  // A 3 V coil would have shifted the reading by 0.28 mV: 13 um at 27 mm (slope -46 mm/V).
  h.input("signals")[0] = quiescent(3.0) + 0.2;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("gap")[0] - 27.1525e-3, -46.0e-3 * (quiescent(3.0) - 2.544), 0.5e-6);
}

TEST(HallDirect, ClampsOutsideTheValidRangeAndCounts) {
  lode::testing::BlockHarness h("estimator.hall_direct", "", 2000.0);
  h.feed("signals", {{"hall", "V"}});
  ASSERT_TRUE(started(h));
  h.input("signals")[0] = 2.0;  // below the quiescent level: no magnet
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("gap")[0], 46.9e-3, 1e-12);
  EXPECT_LT(h.output("compensated")[0], 0.0);
  h.input("signals")[0] = 2.544 + 0.95;  // past 0.8 V, where eq. 16 is no longer valid
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("gap")[0], 16.2902e-3, 1e-6);
  h.input("signals")[0] = 2.544 + 0.3;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  auto& block = dynamic_cast<lode::plugins::HallDirect&>(h.block());
  EXPECT_EQ(block.clamp_count(), 2u);
}

TEST(HallDirect, PicksTheChannelByName) {
  lode::testing::BlockHarness h("estimator.hall_direct", "channel: hall_b\noutput_name: distance", 2000.0);
  h.feed("signals", {{"hall_a", "V"}, {"hall_b", "V"}});
  ASSERT_TRUE(started(h));
  EXPECT_EQ(h.output_elements("gap")[0].name, "distance");
  h.input("signals")[0] = 2.544 + 0.1;
  h.input("signals")[1] = 2.544 + 0.4;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("gap")[0], 21.27e-3, 0.01e-3);
}

TEST(HallDirect, ConfigurationErrors) {
  lode::testing::BlockHarness h("estimator.hall_direct", "channel: hall\ncompensated_range_v: [0.5, 0.2]\n", 2000.0);
  h.feed("signals", {{"a", "V"}, {"b", "V"}});
  h.feed("coil_voltage", {{"coil_voltage", "A"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("signals: no element 'hall' [V] among a [V], b [V]"), std::string::npos) << d;
  EXPECT_NE(d.find("coil_voltage: 'coil_voltage' is in A, expected V"), std::string::npos) << d;
  EXPECT_NE(d.find("compensated_range_v: expected [min, max] with min < max"), std::string::npos) << d;
}

TEST(HallDirect, FaultsOnNonFiniteInputAndDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  lode::testing::BlockHarness h("estimator.hall_direct", "", 2000.0);
  h.feed("signals", {{"hall", "V"}});
  h.feed("coil_voltage", {{"coil_voltage", "V"}});
  ASSERT_TRUE(started(h));
  auto signals = h.input("signals");  // the spans, not a lookup per cycle
  auto coil = h.input("coil_voltage");
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) {
    signals[0] = 2.6 + 1e-5 * k;
    coil[0] = 1.5;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  h.input("signals")[0] = NAN;
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite Hall or coil voltage");
}

}  // namespace
