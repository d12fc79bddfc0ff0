// filter.notch: reference coefficients of the prewarped eq. 31 (Silva-Rivas & Kim 2013) and the
// printed eq. 34's properties, the measured frequency response against the design and the analog
// eq. 31, a 50 Hz line removed from a signal, the depth form, per-channel selection and the
// run-time bypass, configuration errors, faults and no allocation.
#include "notch.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "filter_checks.hpp"
#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/plugin_checks.hpp"

namespace lode::plugins {
namespace {

using lode::testing::BlockHarness;
using lode::testing::member;
using filter::testing::component;

constexpr double kPi = std::numbers::pi;
const Elements kPlanar{{"x", "m"}, {"y", "m"}, {"phi", "rad"}};

/// The 1-channel filter's steady-state gain at f_hz after 1 s: the slowest poles (|z| ~ 0.9)
/// are long settled.
double measured_gain(BlockHarness& h, double f_hz, double rate_hz) {
  return filter::testing::measured_gain(h, f_hz, rate_hz, static_cast<int>(rate_hz));
}

// --- coefficients -------------------------------------------------------------------------

TEST(FilterNotch, Seed003ReferenceCoefficients) {
  // Worked out independently: zeta 0.5, k 0.1, f_notch 50 Hz, Tustin prewarped at 50 Hz, 6 decimals.
  struct Row {
    double fs, b0, b1, a1, a2;
  };
  const Row table[] = {{800.0, 0.097442, -0.180049, -1.867246, 0.882081},
                       {834.2, 0.097408, -0.181163, -1.873066, 0.886719},
                       {1000.0, 0.097387, -0.185240, -1.895301, 0.904834},
                       {2000.0, 0.098117, -0.193817, -1.949047, 0.951463}};
  for (const Row& row : table) {
    BlockHarness h("filter.notch", "f_notch_hz: 50\nk: 0.1\nzeta: 0.5\n", row.fs);
    h.feed("in", kPlanar);
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    const Json d = h.describe();
    const Json& x = member(d, "channels").elements().at(0);
    const auto [b, a] = filter::testing::described_section(x);
    std::printf("fs %6.1f Hz: b = [%.6f, %.6f, %.6f], a = [1, %.6f, %.6f]\n", row.fs, b[0], b[1], b[2], a[1], a[2]);
    EXPECT_NEAR(b[0], row.b0, 6e-7);
    EXPECT_NEAR(b[1], row.b1, 6e-7);
    EXPECT_NEAR(b[2], row.b0, 6e-7);
    EXPECT_NEAR(a[1], row.a1, 6e-7);
    EXPECT_NEAR(a[2], row.a2, 6e-7);
    // "All four give: DC gain 0 dB, an exact null at 50 Hz, and -20.0 dB at Nyquist."
    EXPECT_NEAR(member(x, "dc_gain").as_number(), 1.0, 1e-12);
    EXPECT_NEAR(member(x, "nyquist_gain").as_number(), 0.1, 1e-12);
    EXPECT_LT(member(x, "gain_at_f_notch_db").as_number(), -200.0);
    EXPECT_NEAR(member(x, "zero_frequency_hz").as_number(), 50.0, 1e-9);
    EXPECT_NEAR(member(x, "zero_radius").as_number(), 1.0, 1e-12);
  }
}

TEST(FilterNotch, PrintedEq34PropertiesAt800Hz) {
  // Derived by hand from eq. 34: DC gain 1.028, Nyquist gain 0.1000, zeros at +-0.3766 rad (47.95 Hz at 800 Hz),
  // poles of radius 0.8971 at +-0.0484 rad.
  BlockHarness h("filter.notch", "coefficients: [0.09318, -0.1733, 0.09318, -1.792, 0.8047]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const Json& x = member(d, "channels").elements().at(0);
  EXPECT_EQ(member(x, "form").as_string(), "coefficients");
  EXPECT_NEAR(member(x, "dc_gain").as_number(), 1.028, 0.0005);
  EXPECT_NEAR(member(x, "nyquist_gain").as_number(), 0.1000, 0.00005);
  EXPECT_NEAR(member(x, "zero_angle_rad").as_number(), 0.3766, 0.00005);
  EXPECT_NEAR(member(x, "zero_frequency_hz").as_number(), 47.95, 0.005);
  EXPECT_NEAR(member(x, "pole_radius").as_number(), 0.8971, 0.00005);
  EXPECT_NEAR(member(x, "pole_angle_rad").as_number(), 0.0484, 0.00005);
}

// --- frequency response -------------------------------------------------------------------

TEST(FilterNotch, MeasuredResponseFollowsTheDesignAndTheAnalogEq31) {
  const double fs = 800.0;
  BlockHarness h("filter.notch", "f_notch_hz: 50\n", fs);
  h.feed("in", {{"x", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const Json& x = member(d, "channels").elements().at(0);
  const lode::math::TransferFunction digital = filter::testing::described_section(x);
  const double w0 = 2 * kPi * 50 * std::sqrt(0.1);
  const lode::math::TransferFunction analog{{0.1, 0.0, w0 * w0}, {1.0, w0, w0 * w0}};
  // The analog eq. 31 with zeta = 0.5, computed independently and rounded to 0.1 dB.
  struct Point {
    double f_hz, printed_db;
  };
  const Point points[] = {{5, 0.32}, {10, 0.84}, {15.8, -0.91}, {20, -4.4}, {30, -14.0},
                          {40, -24.4}, {60, -30.0}, {100, -22.4}, {200, -20.5}};
  std::printf("   f [Hz]  measured dB  design dB  analog dB  by hand dB\n");
  for (const Point& p : points) {
    const double measured = 20 * std::log10(measured_gain(h, p.f_hz, fs));
    const double design = 20 * std::log10(std::abs(lode::math::discrete_response(digital, 2 * kPi * p.f_hz, 1 / fs)));
    const double continuous = 20 * std::log10(std::abs(lode::math::continuous_response(analog, 2 * kPi * p.f_hz)));
    std::printf("  %7.1f  %11.4f  %9.4f  %9.4f  %10.2f\n", p.f_hz, measured, design, continuous, p.printed_db);
    EXPECT_NEAR(measured, design, 1e-6) << p.f_hz << " Hz";
    EXPECT_NEAR(continuous, p.printed_db, 0.051) << "the analog eq. 31 reproduces the hand-computed table";
    // Tustin warps frequencies away from 50 Hz: within 0.5 dB of the analog filter to 100 Hz.
    if (p.f_hz <= 100) {
      EXPECT_NEAR(measured, continuous, 0.5) << p.f_hz << " Hz";
    }
  }
}

TEST(FilterNotch, RemovesA50HzLineFromASignal) {
  // 20 um of 50 Hz on a 2 Hz, 1 um motion (x, y); phi is not in `channels` and passes through.
  const double fs = 800.0;
  BlockHarness h("filter.notch", "f_notch_hz: 50\nchannels: [x, y]\n", fs);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  std::vector<double> x_in, x_out, phi_in, phi_out;
  for (int k = 0; k < 3 * static_cast<int>(fs); ++k) {
    const double t = k / fs;
    const double line = 20e-6 * std::sin(2 * kPi * 50 * t + 0.3);
    in[0] = 1e-6 * std::sin(2 * kPi * 2 * t) + line;
    in[1] = line;
    in[2] = line;
    ASSERT_EQ(h.step(), StepStatus::ok);
    if (k >= static_cast<int>(fs)) {  // after 1 s
      x_in.push_back(in[0]);
      x_out.push_back(h.output("out")[0]);
      phi_out.push_back(h.output("out")[2]);
      phi_in.push_back(in[2]);
    }
  }
  const double line_in = std::abs(component(x_in, 50, fs));
  const double line_out = std::abs(component(x_out, 50, fs));
  const double attenuation_db = 20 * std::log10(line_out / line_in);
  std::printf("50 Hz line: %.3g m in, %.3g m out (%.1f dB)\n", line_in, line_out, attenuation_db);
  EXPECT_LT(attenuation_db, -40.0) << "criterion: notch output at the noise floor at 50 Hz (>= 40 dB down)";
  EXPECT_LT(attenuation_db, -150.0) << "the prewarped design puts an exact null at 50 Hz";
  const double motion_gain = std::abs(component(x_out, 2, fs)) / std::abs(component(x_in, 2, fs));
  const Json d = h.describe();
  const Json& x = member(d, "channels").elements().at(0);
  const lode::math::TransferFunction design = filter::testing::described_section(x);
  EXPECT_NEAR(motion_gain, std::abs(lode::math::discrete_response(design, 2 * kPi * 2, 1 / fs)), 1e-6)
      << "the 2 Hz motion passes with the design's gain (+0.05 dB: eq. 31 peaks slightly below w0)";
  EXPECT_NEAR(20 * std::log10(motion_gain), 0.0, 0.1);
  for (std::size_t k = 0; k < phi_in.size(); ++k) ASSERT_EQ(phi_out[k], phi_in[k]);
}

TEST(FilterNotch, DepthFormHasGainKAtTheNotchAndOneElsewhere) {
  const double fs = 1000.0;
  BlockHarness h("filter.notch", "form: depth\nf_notch_hz: 120\nk: 0.05\nzeta: 0.2\n", fs);
  h.feed("in", {{"v", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const Json& v = member(d, "channels").elements().at(0);
  EXPECT_NEAR(member(v, "gain_at_f_notch_db").as_number(), 20 * std::log10(0.05), 1e-9);
  EXPECT_NEAR(member(v, "dc_gain").as_number(), 1.0, 1e-12);
  EXPECT_NEAR(member(v, "nyquist_gain").as_number(), 1.0, 1e-12);
  EXPECT_NEAR(measured_gain(h, 120, fs), 0.05, 1e-6);
  EXPECT_GT(measured_gain(h, 20, fs), 0.99);
}

// --- selection and bypass -----------------------------------------------------------------

TEST(FilterNotch, RunTimeBypassIsExactAndReEnablingHasNoTransient) {
  const double fs = 800.0;
  BlockHarness switched("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", fs);
  BlockHarness always("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", fs);
  for (BlockHarness* h : {&switched, &always}) {
    h->feed("in", kPlanar);
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
  }
  auto& notch = dynamic_cast<NotchFilter&>(switched.block());
  EXPECT_FALSE(notch.set_enabled(std::size_t{2}, true)) << "phi is not a filtered channel";
  EXPECT_TRUE(notch.enabled(0));
  const auto in_switched = switched.input("in");
  const auto in_always = always.input("in");
  for (int k = 0; k < 1200; ++k) {
    if (k == 400) notch.set_enabled(false);
    if (k == 800) notch.set_enabled(true);
    const double value = 1e-5 * std::sin(2 * kPi * 50 * k / fs) + 1e-6 * std::sin(2 * kPi * 3 * k / fs);
    in_switched[0] = in_always[0] = value;
    ASSERT_EQ(switched.step(), StepStatus::ok);
    ASSERT_EQ(always.step(), StepStatus::ok);
    if (k >= 400 && k < 800) {
      ASSERT_EQ(switched.output("out")[0], value) << "bypassed: out = in";
    } else {
      ASSERT_EQ(switched.output("out")[0], always.output("out")[0]) << "cycle " << k;
    }
  }

  BlockHarness off("filter.notch", "f_notch_hz: 50\nenabled: false\n", fs);
  off.feed("in", kPlanar);
  ASSERT_TRUE(off.configure()) << off.diagnostics();
  ASSERT_TRUE(off.activate());
  off.input("in")[1] = 3.0;
  ASSERT_EQ(off.step(), StepStatus::ok);
  EXPECT_EQ(off.output("out")[1], 3.0);
}

// --- errors, faults, allocation -----------------------------------------------------------

void expect_error(const std::string& yaml, const std::string& fragment) {
  BlockHarness h("filter.notch", yaml, 800.0);
  h.feed("in", kPlanar);
  EXPECT_TRUE(lode::testing::configure_fails_with(h, fragment)) << yaml;
}

TEST(FilterNotch, ConfigurationErrorsSayWhatIsWrong) {
  expect_error("f_notch_hz: 400\n", "below Nyquist");
  expect_error("zeta: 0.5\n", "notch frequency [Hz] is required");
  expect_error("f_notch_hz: 50\ncoefficients: [1, 0, 0, 0, 0]\n", "not both");
  expect_error("coefficients: [1, 0, 0, -2.1, 1.2]\n", "unstable denominator");
  expect_error("coefficients: [1, 0, 0, 0]\n", "expected 5 numbers");
  expect_error("f_notch_hz: 50\nk: [0.1, 0.2]\n", "one per filtered channel");
  expect_error("f_notch_hz: 50\nk: 0\n", "must be > 0");
  expect_error("f_notch_hz: 50\nchannels: [x, z]\n", "'z' is not an element");
  expect_error("f_notch_hz: 50\nform: wide\n", "form");
}

TEST(FilterNotch, FaultsOnNonFiniteInputAndDoesNotAllocate) {
  BlockHarness h("filter.notch", "f_notch_hz: [50, 50, 60]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  filter::testing::expect_cycles_allocate_nothing(h, 20000, [&](int k) { in[0] = std::sin(0.3 * k); });
  const double previous = h.output("out")[0];
  in[1] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite input");
  EXPECT_EQ(h.output("out")[0], previous) << "a fault writes nothing";
}

// --- runtime parameters (lode set) --------------------------------------------------------

TEST(FilterNotchTunables, DesignedNotchOffersEnabledFrequencyKAndZeta) {
  BlockHarness h("filter.notch", "f_notch_hz: 50\nk: 0.1\nzeta: 0.5\nchannels: [x, y]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const std::vector<Tunable> t = h.tunables().tunables();
  ASSERT_EQ(t.size(), 4u);
  filter::testing::expect_enabled_tunable(t[0]);
  EXPECT_EQ(t[1].name, "f_notch_hz");
  EXPECT_EQ(t[1].unit, "Hz");
  EXPECT_EQ(t[1].min, 0.0);
  EXPECT_EQ(t[1].max, 400.0);
  EXPECT_EQ(t[2].name, "k");
  EXPECT_EQ(t[3].name, "zeta");
  EXPECT_EQ(h.tunables().tunable_value(0), 1.0);
  EXPECT_EQ(h.tunables().tunable_value(1), 50.0);
  EXPECT_EQ(h.tunables().tunable_value(2), 0.1);
  EXPECT_EQ(h.tunables().tunable_value(3), 0.5);

  BlockHarness raw("filter.notch", "coefficients: [0.09318, -0.1733, 0.09318, -1.792, 0.8047]\n", 800.0);
  raw.feed("in", kPlanar);
  ASSERT_TRUE(raw.configure()) << raw.diagnostics();
  ASSERT_EQ(raw.tunables().tunables().size(), 1u) << "raw coefficients: only enabled";
  const char* why = "";
  EXPECT_FALSE(raw.tunables().set_tunable(1, 60.0, why));
  EXPECT_NE(std::string(why).find("raw coefficients"), std::string::npos) << why;
}

TEST(FilterNotchTunables, ClosedFormDesignEqualsLodeMathTustin) {
  for (const double fs : {800.0, 1000.0, 2000.0}) {
    for (const double f : {5.0, 50.0, 0.45 * fs}) {
      const double w = 2 * kPi * f;
      const double w0 = w * std::sqrt(0.1);
      const auto eq31 = lode::math::tustin(lode::math::TransferFunction{{0.1, 0.0, w0 * w0}, {1.0, 2 * 0.5 * w0, w0 * w0}}, 1 / fs, w);
      const auto depth = lode::math::tustin(lode::math::TransferFunction{{1.0, 2 * 0.05 * 0.3 * w, w * w}, {1.0, 2 * 0.3 * w, w * w}}, 1 / fs, w);
      const notch::Coefficients a = notch::design(notch::Form::eq31, f, 0.1, 0.5, fs);
      const notch::Coefficients b = notch::design(notch::Form::depth, f, 0.05, 0.3, fs);
      const double tol = 1e-12;
      EXPECT_NEAR(a.b0, eq31.num[0], tol);
      EXPECT_NEAR(a.b1, eq31.num[1], tol);
      EXPECT_NEAR(a.b2, eq31.num[2], tol);
      EXPECT_NEAR(a.a1, eq31.den[1], tol);
      EXPECT_NEAR(a.a2, eq31.den[2], tol);
      EXPECT_NEAR(b.b0, depth.num[0], tol);
      EXPECT_NEAR(b.b1, depth.num[1], tol);
      EXPECT_NEAR(b.b2, depth.num[2], tol);
      EXPECT_NEAR(b.a1, depth.den[1], tol);
      EXPECT_NEAR(b.a2, depth.den[2], tol);
    }
  }
}

TEST(FilterNotchTunables, RetuneTakesEffectAtTheNextStepFromTheSignalHistory) {
  const double fs = 800.0;
  BlockHarness h("filter.notch", "form: depth\nf_notch_hz: 50\nk: 0.01\nzeta: 0.3\nchannels: [x]\n", fs);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  auto input = [&](int k) { return 2e-6 + 1e-5 * std::sin(2 * kPi * 60 * k / fs); };  // DC + a 60 Hz line
  std::vector<double> x, y;
  constexpr int kSwitch = 1600;
  for (int k = 0; k < kSwitch; ++k) {
    in[0] = input(k);
    ASSERT_EQ(h.step(), StepStatus::ok);
    x.push_back(in[0]);
    y.push_back(h.output("out")[0]);
  }
  // 60 Hz passes the 50 Hz notch almost untouched.
  const std::vector<double> before(y.end() - 800, y.end());
  const double line_before = std::abs(component(before, 60, fs));
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(1, 60.0, why)) << why;
  EXPECT_EQ(h.tunables().tunable_value(1), 60.0);
  const Json described = h.describe();
  const Json& c = member(described, "channels").elements().at(0);
  const auto [b, a] = filter::testing::described_section(c);
  EXPECT_NEAR(member(c, "gain_at_f_notch_db").as_number(), 20 * std::log10(0.01), 1e-9) << "redesigned at 60 Hz";
  // The next output is the new difference equation on the actual history (direct form I switch).
  in[0] = input(kSwitch);
  ASSERT_EQ(h.step(), StepStatus::ok);
  const double expected = b[0] * in[0] + b[1] * x[kSwitch - 1] + b[2] * x[kSwitch - 2] - a[1] * y[kSwitch - 1] -
                          a[2] * y[kSwitch - 2];
  EXPECT_NEAR(h.output("out")[0], expected, 1e-18);
  std::vector<double> after;
  for (int k = kSwitch + 1; k < kSwitch + 2400; ++k) {
    in[0] = input(k);
    ASSERT_EQ(h.step(), StepStatus::ok);
    if (k >= kSwitch + 1600) after.push_back(h.output("out")[0]);
  }
  const double line_after = std::abs(component(after, 60, fs));
  std::printf("60 Hz line through the notch: %.3g m at 50 Hz, %.3g m after lode set f_notch_hz 60\n", line_before,
              line_after);
  EXPECT_GT(line_before, 0.4e-5) << "60 Hz is on the 50 Hz notch's skirt (zeta = 0.3): about half passes";
  EXPECT_NEAR(line_after, 1e-7, 2e-9) << "the depth form's gain k = 0.01 at the new notch";
}

TEST(FilterNotchTunables, RetuningAtDcHasNoTransient) {
  // A settled DC level through a notch of DC gain 1: re-expressing the state from the history
  // keeps the output exactly at the level; keeping the old state would kick the output.
  BlockHarness h("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  in[0] = 3e-3;
  for (int k = 0; k < 4000; ++k) h.step();
  ASSERT_NEAR(h.output("out")[0], 3e-3, 1e-15);
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(1, 120.0, why)) << why;
  ASSERT_TRUE(h.tunables().set_tunable(3, 0.2, why)) << why;
  ASSERT_TRUE(h.tunables().set_tunable(2, 0.3, why)) << why;
  double worst = 0.0;
  for (int k = 0; k < 2000; ++k) {
    h.step();
    worst = std::max(worst, std::abs(h.output("out")[0] - 3e-3));
  }
  std::printf("DC 3 mm through three retunes: worst deviation %.3g m\n", worst);
  EXPECT_LT(worst, 1e-15);
}

TEST(FilterNotchTunables, RefusedValuesChangeNothing) {
  const double fs = 800.0;
  BlockHarness h("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", fs);
  BlockHarness twin("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", fs);
  for (BlockHarness* b : {&h, &twin}) {
    b->feed("in", kPlanar);
    ASSERT_TRUE(b->configure()) << b->diagnostics();
    ASSERT_TRUE(b->activate());
  }
  for (int k = 0; k < 1000; ++k) {
    if (k == 300) {
      const char* why = "";
      EXPECT_FALSE(h.tunables().set_tunable(1, 400.0, why)) << "Nyquist at 800 Hz";
      EXPECT_NE(std::string(why).find("Nyquist"), std::string::npos) << why;
      EXPECT_FALSE(h.tunables().set_tunable(1, 0.0, why));
      EXPECT_FALSE(h.tunables().set_tunable(2, 0.0, why));
      EXPECT_FALSE(h.tunables().set_tunable(3, -1.0, why));
      EXPECT_FALSE(h.tunables().set_tunable(1, std::nan(""), why));
      EXPECT_FALSE(h.tunables().set_tunable(0, 0.5, why));
      EXPECT_FALSE(h.tunables().set_tunable(4, 1.0, why));
      EXPECT_EQ(h.tunables().tunable_value(1), 50.0);
      EXPECT_EQ(h.tunables().tunable_value(0), 1.0);
    }
    h.input("in")[0] = twin.input("in")[0] = std::sin(0.37 * k);
    h.step();
    twin.step();
    ASSERT_EQ(h.output("out")[0], twin.output("out")[0]) << k;
  }
}

TEST(FilterNotchTunables, EnabledSwitchesBypass) {
  BlockHarness h("filter.notch", "f_notch_hz: 50\nchannels: [x]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(0, 0.0, why)) << why;
  EXPECT_EQ(h.tunables().tunable_value(0), 0.0);
  h.input("in")[0] = 1.0;
  h.step();
  EXPECT_EQ(h.output("out")[0], 1.0) << "bypassed: out = in";
  ASSERT_TRUE(h.tunables().set_tunable(0, 1.0, why)) << why;
  h.step();
  EXPECT_NE(h.output("out")[0], 1.0) << "filtering again (a unit step is still settling)";
}

TEST(FilterNotchTunables, SetTunableAllocatesNothing) {
  BlockHarness h("filter.notch", "f_notch_hz: [50, 50, 60]\n", 800.0);
  h.feed("in", kPlanar);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const auto in = h.input("in");
  const char* why = "";
  filter::testing::expect_set_tunables_allocate_nothing(h, 1000, 3000, [&](Tunables& block, int k) {
    int accepted = block.set_tunable(1, (k % 2) ? 50.0 : 60.0, why) ? 1 : 0;
    accepted += block.set_tunable(3, (k % 2) ? 0.5 : 0.3, why) ? 1 : 0;
    accepted += block.set_tunable(0, (k % 3) ? 1.0 : 0.0, why) ? 1 : 0;
    (void)block.set_tunable(1, 400.0, why);
    in[0] = std::sin(0.3 * k);
    return accepted;
  });
}

}  // namespace
}  // namespace lode::plugins
