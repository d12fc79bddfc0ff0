// filter.external_gain through the BlockHarness of the installed SDK: the output is the gain
// times the input at every step, element names and units pass through, and a missing gain is
// refused with the parameter's name.
#include <gtest/gtest.h>

#include <lode/sdk/testing/harness.hpp>

namespace {

TEST(ExternalGain, OutputIsGainTimesInputWithTheInputsElements) {
  lode::testing::BlockHarness h("filter.external_gain", "gain: 3.0", 1000.0);
  h.feed("input", {{"x", "m"}, {"theta_z", "rad"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto& elements = h.output_elements("out");
  ASSERT_EQ(elements.size(), 2u);
  EXPECT_EQ(elements[1].name, "theta_z");
  EXPECT_EQ(elements[1].unit, "rad");
  for (const double v : {0.0, 1.5, -2.25}) {
    h.input("input")[0] = v;
    h.input("input")[1] = 2.0 * v;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    EXPECT_EQ(h.output("out")[0], 3.0 * v);
    EXPECT_EQ(h.output("out")[1], 6.0 * v);
  }
}

TEST(ExternalGain, AMissingGainIsRefusedByName) {
  lode::testing::BlockHarness h("filter.external_gain", "{}", 1000.0);
  h.feed("input", {{"x", "m"}});
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("gain"), std::string::npos) << h.diagnostics();
}

}  // namespace
