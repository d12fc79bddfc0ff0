// filter.biquad: the designed forms against the RBJ cookbook closed forms, measured responses
// at their defining frequencies, raw coefficients against a direct-form-I reference, per-channel
// coefficients, channel selection and bypass, configuration errors, faults and no allocation.
#include "biquad.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "filter_checks.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/plugin_checks.hpp"

namespace lode::plugins {
namespace {

using lode::testing::BlockHarness;
using lode::testing::member;

constexpr double kPi = std::numbers::pi;

/// RBJ cookbook (w = 2 pi f / fs, alpha = sin w / 2Q), normalised by a0: [b0, b1, b2, a1, a2].
std::array<double, 5> cookbook(const std::string& type, double f, double q, double fs) {
  const double w = 2 * kPi * f / fs;
  const double cw = std::cos(w);
  const double alpha = std::sin(w) / (2 * q);
  std::array<double, 3> b{};
  if (type == "lowpass") b = {(1 - cw) / 2, 1 - cw, (1 - cw) / 2};
  if (type == "highpass") b = {(1 + cw) / 2, -(1 + cw), (1 + cw) / 2};
  if (type == "bandpass") b = {alpha, 0.0, -alpha};
  if (type == "notch") b = {1.0, -2 * cw, 1.0};
  const double a0 = 1 + alpha;
  return {b[0] / a0, b[1] / a0, b[2] / a0, -2 * cw / a0, (1 - alpha) / a0};
}

TEST(FilterBiquad, DesignedFormsEqualTheCookbook) {
  struct Case {
    const char* type;
    double f, q, fs;
  };
  const Case cases[] = {{"lowpass", 100, 0.7071067811865476, 1000}, {"highpass", 100, 0.7071067811865476, 1000},
                        {"bandpass", 50, 5, 800},                   {"notch", 50, 5, 800},
                        {"lowpass", 300, 2, 800},                   {"highpass", 2, 0.5, 800}};
  for (const Case& c : cases) {
    char yaml[128];
    std::snprintf(yaml, sizeof yaml, "type: %s\nf_hz: %.17g\nq: %.17g\n", c.type, c.f, c.q);
    BlockHarness h("filter.biquad", yaml, c.fs);
    h.feed("in", {{"x", "m"}});
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    const Json d = h.describe();
    const Json& x = member(d, "channels").elements().at(0);
    const auto [b, a] = filter::testing::described_section(x);
    const std::array<double, 5> expected = cookbook(c.type, c.f, c.q, c.fs);
    const std::array<double, 5> got{b[0], b[1], b[2], a[1], a[2]};
    for (std::size_t i = 0; i < 5; ++i) {
      EXPECT_NEAR(got[i], expected[i], 1e-13 * std::max(1.0, std::abs(expected[i]))) << c.type << " " << c.f << " [" << i << "]";
    }
  }
}

TEST(FilterBiquad, MeasuredResponsesAtTheirDefiningFrequencies) {
  const double fs = 1000.0;
  auto gain = [&](const std::string& yaml, double f) {
    BlockHarness h("filter.biquad", yaml, fs);
    h.feed("in", {{"x", "m"}});
    EXPECT_TRUE(h.configure()) << h.diagnostics();
    return filter::testing::measured_gain(h, f, fs, 4 * static_cast<int>(fs));
  };
  // Butterworth low/high-pass: -3.01 dB exactly at the (prewarped) corner.
  EXPECT_NEAR(gain("type: lowpass\nf_hz: 100\n", 100), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(gain("type: lowpass\nf_hz: 100\n", 2), 1.0, 1e-3);
  EXPECT_NEAR(gain("type: highpass\nf_hz: 100\n", 100), std::sqrt(0.5), 1e-6);
  EXPECT_LT(gain("type: highpass\nf_hz: 100\n", 2), 1e-3);
  // Band-pass: 0 dB at the centre; notch: a null there, unity far away.
  EXPECT_NEAR(gain("type: bandpass\nf_hz: 60\nq: 4\n", 60), 1.0, 1e-6);
  EXPECT_LT(gain("type: bandpass\nf_hz: 60\nq: 4\n", 6), 0.05);
  EXPECT_LT(gain("type: notch\nf_hz: 60\nq: 4\n", 60), 1e-9);
  EXPECT_NEAR(gain("type: notch\nf_hz: 60\nq: 4\n", 6), 1.0, 2e-3);
}

TEST(FilterBiquad, RawCoefficientsRunTheDifferenceEquation) {
  // Eq. 34 on x, a low-pass on y (5 per channel); compared with the direct form I
  // y_k = b0 x_k + b1 x_{k-1} + b2 x_{k-2} - a1 y_{k-1} - a2 y_{k-2}.
  const std::array<std::array<double, 5>, 2> c = {{{0.09318, -0.1733, 0.09318, -1.792, 0.8047},
                                                   {0.02, 0.04, 0.02, -1.56, 0.64}}};
  BlockHarness h("filter.biquad",
                 "type: coefficients\ncoefficients: [0.09318, -0.1733, 0.09318, -1.792, 0.8047, "
                 "0.02, 0.04, 0.02, -1.56, 0.64]\n",
                 800.0);
  h.feed("in", {{"x", "m"}, {"y", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::array<std::array<double, 2>, 2> x_past{}, y_past{};
  const auto in = h.input("in");
  for (int k = 0; k < 2000; ++k) {
    for (std::size_t ch = 0; ch < 2; ++ch) in[ch] = noise(rng);
    ASSERT_EQ(h.step(), StepStatus::ok);
    for (std::size_t ch = 0; ch < 2; ++ch) {
      const auto& k5 = c[ch];
      const double y = k5[0] * in[ch] + k5[1] * x_past[ch][0] + k5[2] * x_past[ch][1] - k5[3] * y_past[ch][0] -
                       k5[4] * y_past[ch][1];
      ASSERT_NEAR(h.output("out")[ch], y, 1e-12 * (1 + std::abs(y))) << "channel " << ch << ", cycle " << k;
      x_past[ch] = {in[ch], x_past[ch][0]};
      y_past[ch] = {y, y_past[ch][0]};
    }
  }
}

TEST(FilterBiquad, ChannelSelectionAndBypass) {
  BlockHarness h("filter.biquad", "type: lowpass\nf_hz: 10\nchannels: [b]\n", 1000.0);
  h.feed("in", {{"a", "V"}, {"b", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto& biquad = dynamic_cast<BiquadFilter&>(h.block());
  EXPECT_FALSE(biquad.set_enabled(std::size_t{0}, true)) << "a is not filtered";
  const auto in = h.input("in");
  in[0] = in[1] = 1.0;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_EQ(h.output("out")[0], 1.0);
  EXPECT_LT(h.output("out")[1], 0.01) << "a 10 Hz low-pass barely moves on the first sample";
  biquad.set_enabled(false);
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_EQ(h.output("out")[1], 1.0);
  EXPECT_FALSE(biquad.enabled(1));
  biquad.set_enabled(true);
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_LT(h.output("out")[1], 0.1) << "filtered again, continuing from the section's own state";
}

void expect_error(const std::string& yaml, const std::string& fragment) {
  BlockHarness h("filter.biquad", yaml, 800.0);
  h.feed("in", {{"x", "m"}, {"y", "m"}});
  EXPECT_TRUE(lode::testing::configure_fails_with(h, fragment)) << yaml;
}

TEST(FilterBiquad, ConfigurationErrorsSayWhatIsWrong) {
  expect_error("f_hz: 10\n", "type");
  expect_error("type: lowpass\n", "frequency [Hz] is required");
  expect_error("type: lowpass\nf_hz: 400\n", "below Nyquist");
  expect_error("type: lowpass\nf_hz: 10\nq: 0\n", "quality factor must be > 0");
  expect_error("type: lowpass\nf_hz: 10\ncoefficients: [1, 0, 0, 0, 0]\n", "need type: coefficients");
  expect_error("type: coefficients\ncoefficients: [1, 0, 0, 0, 1.0]\n", "unstable denominator");
  expect_error("type: coefficients\ncoefficients: [1, 0, 0, 0, 0, 1]\n", "5 per filtered channel");
  expect_error("type: coefficients\n", "needs [b0, b1, b2, a1, a2]");
}

TEST(FilterBiquad, FaultsOnNonFiniteInputAndDoesNotAllocate) {
  BlockHarness h("filter.biquad", "type: bandpass\nf_hz: [50, 70]\nq: 3\n", 800.0);
  h.feed("in", {{"x", "m"}, {"y", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  filter::testing::expect_cycles_allocate_nothing(h, 20000, [&](int k) {
    in[0] = std::sin(0.4 * k);
    in[1] = std::cos(0.5 * k);
  });
  in[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite input");
}

// --- runtime parameter (lode set) ---------------------------------------------------------

TEST(FilterBiquadTunables, EnabledIsABoolAndSwitchesBypassAtTheNextStep) {
  BlockHarness h("filter.biquad", "type: lowpass\nf_hz: 10\nchannels: [b]\n", 1000.0);
  h.feed("in", {{"a", "V"}, {"b", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const std::vector<Tunable> t = h.tunables().tunables();
  ASSERT_EQ(t.size(), 1u);
  filter::testing::expect_enabled_tunable(t[0]);
  EXPECT_EQ(h.tunables().tunable_value(0), 1.0);
  const auto in = h.input("in");
  in[0] = in[1] = 1.0;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_LT(h.output("out")[1], 0.01);
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(0, 0.0, why)) << why;
  EXPECT_EQ(h.tunables().tunable_value(0), 0.0);
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_EQ(h.output("out")[1], 1.0) << "bypassed: out = in";
  ASSERT_TRUE(h.tunables().set_tunable(0, 1.0, why)) << why;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_LT(h.output("out")[1], 0.1) << "filtered again from the section's own state";
}

TEST(FilterBiquadTunables, RefusedValuesChangeNothing) {
  BlockHarness h("filter.biquad", "type: lowpass\nf_hz: 10\n", 1000.0);
  h.feed("in", {{"a", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const char* why = "";
  EXPECT_FALSE(h.tunables().set_tunable(0, 0.5, why));
  EXPECT_STRNE(why, "");
  why = "";
  EXPECT_FALSE(h.tunables().set_tunable(0, std::nan(""), why));
  EXPECT_STRNE(why, "");
  why = "";
  EXPECT_FALSE(h.tunables().set_tunable(1, 0.0, why));
  EXPECT_STRNE(why, "");
  EXPECT_EQ(h.tunables().tunable_value(0), 1.0);
  h.input("in")[0] = 1.0;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_LT(h.output("out")[0], 0.01) << "still filtering";
}

TEST(FilterBiquadTunables, SetTunableAllocatesNothing) {
  BlockHarness h("filter.biquad", "type: bandpass\nf_hz: [50, 70]\nq: 3\n", 800.0);
  h.feed("in", {{"x", "m"}, {"y", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  const char* why = "";
  filter::testing::expect_set_tunables_allocate_nothing(h, 1000, 1000, [&](Tunables& block, int k) {
    const int accepted = block.set_tunable(0, (k % 2) ? 1.0 : 0.0, why) ? 1 : 0;
    (void)block.set_tunable(0, 0.5, why);
    in[0] = std::sin(0.4 * k);
    return accepted;
  });
}

}  // namespace
}  // namespace lode::plugins
