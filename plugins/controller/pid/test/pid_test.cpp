// controller.pid: the gains-to-recursion design against a parallel PID written out, eq. 35's
// coefficients literally (and their roots), the clamp and its anti-windup, setpoint
// weights, choosing the axis by name, configuration errors and no allocation in step().
#include "pid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

constexpr double kRate = 2000.0;
constexpr double kT = 1.0 / kRate;

TEST(PidDesign, RecursionEqualsTheParallelPid) {
  // kp + ki/s + kd N s/(s + N): trapezoidal integrator, Tustin-filtered derivative, summed.
  const lode::plugins::pid::Gains g{-750.0, -4700.0, -18.8, 300.0, 1.0, 1.0};
  const auto r = lode::plugins::pid::design(g, kT);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> e_dist(-1e-3, 1e-3);
  double integral = 0.0, derivative = 0.0, e1 = 0.0;
  double u1 = 0.0, u2 = 0.0, ee1 = 0.0, ee2 = 0.0;
  const double p = (2.0 - g.derivative_filter_rad_s * kT) / (2.0 + g.derivative_filter_rad_s * kT);
  const double c = 2.0 * g.kd * g.derivative_filter_rad_s / (2.0 + g.derivative_filter_rad_s * kT);
  double worst = 0.0;
  for (int k = 0; k < 2000; ++k) {
    const double e = e_dist(rng);
    integral += 0.5 * g.ki * kT * (e + e1);
    derivative = p * derivative + c * (e - e1);
    const double parallel = g.kp * e + integral + derivative;
    const double u = -r.denominator[0] * u1 - r.denominator[1] * u2 + r.error_numerator[0] * e +
                     r.error_numerator[1] * ee1 + r.error_numerator[2] * ee2;
    worst = std::max(worst, std::abs(u - parallel));
    u2 = u1;
    u1 = u;
    ee2 = ee1;
    ee1 = e;
    e1 = e;
  }
  EXPECT_LT(worst, 1e-10);
  EXPECT_NEAR(r.denominator[0], -(1.0 + p), 1e-15);
  EXPECT_NEAR(r.denominator[1], p, 1e-15);
}

TEST(PidDesign, TheDerivativePoleOfEq35IsAFilterNear991RadPerSecond) {
  // Eq. 35's 0.603 is the pole of a Tustin-filtered derivative with N = 991 rad/s at 2 kHz.
  const double N = 2.0 / kT * (1.0 - 0.603) / (1.0 + 0.603);
  EXPECT_NEAR(N, 990.6, 0.1);
  const auto r = lode::plugins::pid::design({1.0, 1.0, 1.0, N, 1.0, 1.0}, kT);
  EXPECT_NEAR(r.denominator[0], -1.603, 1e-12);
  EXPECT_NEAR(r.denominator[1], 0.603, 1e-12);
}

TEST(PidDesign, Eq35RootsAsPrinted) {
  // Denominator 1 - 1.604 z^-1 + 0.603 z^-2: roots 1.0025 and 0.6015 (a rounded 1 - z^-1 factor);
  // numerator -623.9 + 1020 z^-1 - 386.8 z^-2: roots 0.598 and 1.037, coefficient sum 9.3.
  const auto poles = lode::plugins::pid::quadratic_roots(1.0, -1.604, 0.603);
  ASSERT_EQ(poles.size(), 2u);
  EXPECT_NEAR(poles[0][0], 1.0025, 5e-5);
  EXPECT_NEAR(poles[1][0], 0.6015, 5e-5);
  const auto zeros = lode::plugins::pid::quadratic_roots(-623.9, 1020.0, -386.8);
  EXPECT_NEAR(zeros[0][0], 1.037, 5e-4);
  EXPECT_NEAR(zeros[1][0], 0.598, 5e-4);
  const auto complex_pair = lode::plugins::pid::quadratic_roots(1.0, 0.0, 1.0);
  EXPECT_NEAR(std::abs(complex_pair[0][1]), 1.0, 1e-15);
}

const char* const kEq35 =
    "coefficients: {numerator: [-623.9, 1020, -386.8], denominator: [1, -1.604, 0.603]}\n"
    "output_min: 0.5\noutput_max: 3\ninitial_output: 1.5\n"
    "output_names: [coil_voltage]\noutput_units: [V]\n";

TEST(PidBlock, Eq35LiterallyWithinTheLimits) {
  lode::testing::BlockHarness h("controller.pid", kEq35, kRate);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("reference", {{"gap", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  EXPECT_EQ(h.output_elements("out")[0].name, "coil_voltage");
  EXPECT_EQ(h.output_elements("out")[0].unit, "V");
  EXPECT_EQ(h.output("out")[0], 1.5);
  // Small errors keep u inside (0.5, 3): the output is the printed difference equation.
  double u1 = 1.5, u2 = 1.5, e1 = 0.0, e2 = 0.0;
  for (int k = 0; k < 50; ++k) {
    const double e = 1e-4 * std::sin(0.3 * k);
    h.input("reference")[0] = 0.025;
    h.input("measurement")[0] = 0.025 - e;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    const double expected = 1.604 * u1 - 0.603 * u2 - 623.9 * e + 1020 * e1 - 386.8 * e2;
    ASSERT_GT(expected, 0.5);
    ASSERT_LT(expected, 3.0);
    EXPECT_NEAR(h.output("out")[0], expected, 1e-12) << k;
    u2 = u1;
    u1 = expected;
    e2 = e1;
    e1 = e;
  }
  const lode::Json d = h.describe();
  const lode::Json& axis = d.find("axes")->elements()[0];
  EXPECT_NEAR(axis.find("poles_z")->elements()[0].find("re")->as_number(), 1.0025, 5e-5);
}

TEST(PidBlock, ClampAndAntiWindup) {
  // A long positive error saturates the output at 3 V. Because the recursion remembers the
  // clamped value, the output leaves the limit as soon as the error reverses (no windup).
  lode::testing::BlockHarness h("controller.pid",
                                "kp: 10\nki: 100\noutput_min: 0.5\noutput_max: 3\ninitial_output: 1\n", kRate);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("reference", {{"gap", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.input("reference")[0] = 1.0;
  h.input("measurement")[0] = 0.0;  // e = 1 for 2 s: an unclamped integrator would reach ~200
  for (int k = 0; k < 4000; ++k) {
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    EXPECT_LE(h.output("out")[0], 3.0);
  }
  EXPECT_EQ(h.output("out")[0], 3.0);
  auto& pid = dynamic_cast<lode::plugins::PidController&>(h.block());
  EXPECT_GT(pid.saturation_count(), 3900u);
  h.input("measurement")[0] = 1.2;  // e = -0.2: the P part alone takes 2 V off at once
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_LT(h.output("out")[0], 1.5);
  for (int k = 0; k < 4000; ++k) ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_EQ(h.output("out")[0], 0.5);
}

TEST(PidBlock, SetpointWeightsRemoveTheKick) {
  // With beta = gamma = 0 a reference step enters through the integral only.
  const std::string gains = "kp: -750\nki: -4700\nkd: -18.8\nderivative_filter_rad_s: 300\n";
  for (const double weight : {1.0, 0.0}) {
    lode::testing::BlockHarness h("controller.pid",
                                  gains + "setpoint_weight_p: " + std::to_string(weight) +
                                      "\nsetpoint_weight_d: " + std::to_string(weight) + "\n",
                                  kRate);
    h.feed("measurement", {{"gap", "m"}});
    h.feed("reference", {{"gap", "m"}});
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    ASSERT_TRUE(h.activate());
    h.input("reference")[0] = 0.026;
    h.input("measurement")[0] = 0.026;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    const double before = h.output("out")[0];
    h.input("reference")[0] = 0.022;  // 4 mm step
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    const double jump = h.output("out")[0] - before;
    const double integral_only = 0.5 * -4700.0 * kT * (-0.004);
    if (weight == 0.0) {
      EXPECT_NEAR(jump, integral_only, 1e-12);
    } else {
      EXPECT_GT(std::abs(jump), 100.0 * std::abs(integral_only)) << "the kick of P and D";
    }
  }
}

TEST(PidBlock, ControlsTheNamedElementOfAStateVector) {
  lode::testing::BlockHarness h("controller.pid", "kp: 2\noutput_names: [coil_voltage]\noutput_units: [V]\n", kRate);
  h.feed("measurement", {{"gap", "m"}, {"velocity", "m/s"}, {"current", "A"}});
  h.feed("reference", {{"gap", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.input("measurement")[0] = 0.020;
  h.input("measurement")[1] = 5.0;
  h.input("measurement")[2] = 7.0;
  h.input("reference")[0] = 0.025;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_EQ(h.output("out")[0], 0.0);  // bumpless start from initial_output
  h.input("measurement")[0] = 0.021;    // only the gap counts: velocity and current ignored
  h.input("measurement")[1] = -3.0;
  h.input("measurement")[2] = 1.0;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("out")[0], 2.0 * -0.001, 1e-15);
  lode::testing::BlockHarness by_axes("controller.pid", "kp: 1\naxes: [current]\n", kRate);
  by_axes.feed("measurement", {{"gap", "m"}, {"velocity", "m/s"}, {"current", "A"}});
  ASSERT_TRUE(by_axes.configure()) << by_axes.diagnostics();
  ASSERT_TRUE(by_axes.activate());
  ASSERT_EQ(by_axes.step(), lode::StepStatus::ok);
  by_axes.input("measurement")[2] = 0.25;
  ASSERT_EQ(by_axes.step(), lode::StepStatus::ok);
  EXPECT_NEAR(by_axes.output("out")[0], -0.25, 1e-15);  // no reference: r = 0
  EXPECT_EQ(by_axes.output_elements("out")[0].name, "u_current");
}

TEST(PidBlock, ConfigurationErrors) {
  lode::testing::BlockHarness h("controller.pid",
                                "kp: 1\nkd: 2\ncoefficients: {numerator: [1, 2, 3, 4], denominator: [0]}\n"
                                "output_min: 3\noutput_max: 1\n",
                                kRate);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("reference", {{"gap", "mm"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* what : {"coefficients: give either coefficients", "numerator: expected 1 to 3",
                           "denominator: expected 1 to 3 numbers a0, a1, a2 with a0 != 0",
                           "output_min: output_min must be < output_max", "reference 'gap' is in mm"}) {
    EXPECT_NE(d.find(what), std::string::npos) << what << "\n" << d;
  }
  lode::testing::BlockHarness h2("controller.pid", "kd: 2\ninitial_output: 9\noutput_max: 3\naxes: [speed]\n", kRate);
  h2.feed("measurement", {{"gap", "m"}});
  EXPECT_FALSE(h2.configure());
  const std::string d2 = h2.diagnostics();
  EXPECT_NE(d2.find("axes: no element 'speed'"), std::string::npos) << d2;
  lode::testing::BlockHarness h3("controller.pid", "kd: 2\n", kRate);
  h3.feed("measurement", {{"gap", "m"}});
  EXPECT_FALSE(h3.configure());
  EXPECT_NE(h3.diagnostics().find("derivative_filter_rad_s: a derivative part needs its filter"), std::string::npos)
      << h3.diagnostics();
  lode::testing::BlockHarness h4("controller.pid", "output_max: 3\n", kRate);
  h4.feed("measurement", {{"gap", "m"}});
  EXPECT_FALSE(h4.configure());
  EXPECT_NE(h4.diagnostics().find("kp: give PID gains"), std::string::npos) << h4.diagnostics();
}

TEST(PidBlock, FaultsAndDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  lode::testing::BlockHarness h("controller.pid", kEq35, kRate);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("reference", {{"gap", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");  // the spans, not a lookup per cycle
  auto reference = h.input("reference");
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) {
    measurement[0] = 0.025 + 1e-4 * std::sin(0.01 * k);
    reference[0] = 0.025;
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  h.input("measurement")[0] = NAN;
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement or reference");
}

// ---- Runtime parameters (lode set) ----

/// Positional PID with the bumpless-transfer semantics the block promises for a gain change:
/// u(k-1) and the filtered derivative Df are kept, the integrator absorbs the change.
struct PositionalPid {
  double kp, ki, kd, n_rad_s, t_s;
  double integral = 0.0, df = 0.0, e1 = 0.0, d1 = 0.0, r1 = 0.0, y1 = 0.0, u1 = 0.0;
  bool first = true;
  double step(double r, double y) {
    const double p = (2.0 - n_rad_s * t_s) / (2.0 + n_rad_s * t_s);
    const double g = 2.0 * n_rad_s / (2.0 + n_rad_s * t_s);
    const double e = r - y, d = r - y;
    if (first) {
      e1 = e, d1 = d, r1 = r, y1 = y;
      integral = 0.0 - kp * (r - y);  // u(-1) = initial_output = 0
      first = false;
    }
    integral += 0.5 * ki * t_s * (e + e1);
    df = p * df + g * (d - d1);
    u1 = kp * (r - y) + integral + kd * df;
    e1 = e, d1 = d, r1 = r, y1 = y;
    return u1;
  }
  void set_gains(double new_kp, double new_ki, double new_kd) {
    integral = u1 - new_kp * (r1 - y1) - new_kd * df;
    kp = new_kp, ki = new_ki, kd = new_kd;
  }
};

TEST(PidTunables, GainsAndLimitsForEveryAxisAndEachAxis) {
  lode::testing::BlockHarness h("controller.pid", "kp: 2\nki: [10, 20]\nkd: 0.01\nderivative_filter_rad_s: 300\n"
                                                  "output_min: -5\noutput_max: 5\noutput_units: [V]\n", 1000.0);
  h.feed("measurement", {{"x", "m"}, {"y", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const std::vector<lode::Tunable> t = h.tunables().tunables();
  std::vector<std::string> names;
  for (const auto& tunable : t) names.push_back(tunable.name);
  const std::vector<std::string> expected{"kp", "kp.x", "kp.y", "ki", "ki.x", "ki.y", "kd", "kd.x", "kd.y",
                                          "output_min", "output_min.x", "output_min.y",
                                          "output_max", "output_max.x", "output_max.y"};
  EXPECT_EQ(names, expected);
  ASSERT_EQ(t.size(), 15u);
  EXPECT_EQ(t[0].unit, "V/m");
  EXPECT_EQ(t[4].unit, "V/(m*s)");
  EXPECT_EQ(t[8].unit, "V*s/m");
  EXPECT_EQ(t[9].unit, "V");
  EXPECT_FALSE(t[0].integer);
  EXPECT_EQ(h.tunables().tunable_value(5), 20.0);   // ki.y
  EXPECT_EQ(h.tunables().tunable_value(3), 10.0);   // ki: axis x's
  EXPECT_EQ(h.tunables().tunable_value(14), 5.0);   // output_max.y

  lode::testing::BlockHarness raw("controller.pid",
                                  "coefficients: {numerator: [-623.9, 1020, -386.8], denominator: [1, -1.604, 0.603]}\n"
                                  "output_min: 0.5\noutput_max: 3\n", kRate);
  raw.feed("measurement", {{"gap", "m"}});
  ASSERT_TRUE(raw.configure()) << raw.diagnostics();
  const std::vector<lode::Tunable> limits = raw.tunables().tunables();
  ASSERT_EQ(limits.size(), 2u) << "coefficients: only the limits";
  EXPECT_EQ(limits[0].name, "output_min");
  EXPECT_EQ(raw.tunables().tunable_value(1), 3.0);
}

TEST(PidTunables, GainChangesAreBumplessAndFollowThePositionalPid) {
  const double rate = 1000.0, T = 1.0 / rate;
  lode::testing::BlockHarness h("controller.pid", "kp: 2\nki: 50\nkd: 0.01\nderivative_filter_rad_s: 200\n", rate);
  h.feed("measurement", {{"x", "m"}});
  h.feed("reference", {{"x", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");
  auto reference = h.input("reference");
  PositionalPid model{2.0, 50.0, 0.01, 200.0, T};
  double worst = 0.0, step_at_ki_switch = 0.0, naive_jump = 0.0;
  for (int k = 0; k < 1200; ++k) {
    const char* why = "";
    if (k == 300) {  // ki 50 -> 120
      naive_jump = std::abs((120.0 - 50.0) / 50.0 * (model.u1 - 2.0 * (model.r1 - model.y1) - 0.01 * model.df));
      ASSERT_TRUE(h.tunables().set_tunable(1, 120.0, why)) << why;
      model.set_gains(2.0, 120.0, 0.01);
    }
    if (k == 600) {  // kp 2 -> 0.5
      ASSERT_TRUE(h.tunables().set_tunable(0, 0.5, why)) << why;
      model.set_gains(0.5, 120.0, 0.01);
    }
    if (k == 900) {  // kd 0.01 -> 0.03 (the derivative filter is still ringing from the y step)
      ASSERT_TRUE(h.tunables().set_tunable(2, 0.03, why)) << why;
      model.set_gains(0.5, 120.0, 0.03);
    }
    const double r = k >= 50 ? 1e-3 : 0.0;
    const double y = 5e-4 * std::sin(2 * std::numbers::pi * 3 * k * T) + (k >= 880 ? 2e-4 : 0.0);
    measurement[0] = y;
    reference[0] = r;
    const double before = h.output("out")[0];
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    const double u = h.output("out")[0];
    const double expected = model.step(r, y);
    worst = std::max(worst, std::abs(u - expected));
    if (k == 300) step_at_ki_switch = std::abs(u - before);
  }
  std::printf("ki 50 -> 120 at cycle 300: output step %.3g (a positional PID without bumpless transfer: %.3g); "
              "worst |block - positional bumpless model| over kp, ki, kd switches %.3g\n",
              step_at_ki_switch, naive_jump, worst);
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(step_at_ki_switch, 0.1 * naive_jump);
  EXPECT_EQ(h.tunables().tunable_value(0), 0.5);
  EXPECT_EQ(h.tunables().tunable_value(1), 120.0);
  EXPECT_EQ(h.tunables().tunable_value(2), 0.03);
}

TEST(PidTunables, ConstantErrorKeepsRampingAtTheNewIntegralRate) {
  lode::testing::BlockHarness h("controller.pid", "kp: 3\nki: 10\n", kRate);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  h.input("measurement")[0] = -0.2;  // e = 0.2 without a reference
  for (int k = 0; k < 100; ++k) h.step();
  const double u_before = h.output("out")[0];
  const char* why = "";
  ASSERT_TRUE(h.tunables().set_tunable(1, 40.0, why)) << why;  // ki
  ASSERT_TRUE(h.tunables().set_tunable(0, 9.0, why)) << why;   // kp: a constant error gives no P increment
  h.step();
  EXPECT_NEAR(h.output("out")[0] - u_before, 40.0 * kT * 0.2, 1e-14);
  h.step();
  EXPECT_NEAR(h.output("out")[0] - u_before, 2 * 40.0 * kT * 0.2, 1e-14);
}

TEST(PidTunables, LimitsApplyFromTheNextOutputAndRefusalsChangeNothing) {
  const std::string params = "kp: 2\nki: 400\noutput_min: -5\noutput_max: 5\n";
  lode::testing::BlockHarness h("controller.pid", params, kRate);
  lode::testing::BlockHarness twin("controller.pid", params, kRate);
  for (auto* b : {&h, &twin}) {
    b->feed("measurement", {{"x", "m"}, {"y", "m"}});
    ASSERT_TRUE(b->configure()) << b->diagnostics();
    ASSERT_TRUE(b->activate());
  }
  auto run = [&](lode::testing::BlockHarness& b) {
    b.input("measurement")[0] = -1.0;
    b.input("measurement")[1] = -1.0;
    return b.step();
  };
  for (int k = 0; k < 20; ++k) {
    run(h);
    run(twin);
  }
  ASSERT_GT(h.output("out")[1], 2.0);
  const char* why = "";
  // Refusals first: nothing may change.
  EXPECT_FALSE(h.tunables().set_tunable(14, -6.0, why)) << "output_max.y below output_min";
  EXPECT_NE(std::string(why).find("output_min"), std::string::npos) << why;
  EXPECT_FALSE(h.tunables().set_tunable(10, 5.0, why)) << "output_min = output_max";
  EXPECT_FALSE(h.tunables().set_tunable(0, std::nan(""), why));
  EXPECT_FALSE(h.tunables().set_tunable(6, 1.0, why)) << "kd without a derivative filter";
  EXPECT_NE(std::string(why).find("derivative_filter_rad_s"), std::string::npos) << why;
  EXPECT_FALSE(h.tunables().set_tunable(15, 1.0, why));
  for (int k = 0; k < 20; ++k) {
    run(h);
    run(twin);
    ASSERT_EQ(h.output("out")[0], twin.output("out")[0]);
    ASSERT_EQ(h.output("out")[1], twin.output("out")[1]);
  }
  EXPECT_EQ(h.tunables().tunable_value(14), 5.0);
  // output_max.y = 2: y's next output sits on the new limit, x's is untouched.
  ASSERT_TRUE(h.tunables().set_tunable(14, 2.0, why)) << why;
  run(h);
  run(twin);
  EXPECT_EQ(h.output("out")[1], 2.0);
  EXPECT_EQ(h.output("out")[0], twin.output("out")[0]);
}

TEST(PidTunables, SetTunableAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  lode::testing::BlockHarness h("controller.pid", "kp: 2\nki: 40\nkd: 0.01\nderivative_filter_rad_s: 300\n"
                                                  "output_min: -5\noutput_max: 5\n", kRate);
  h.feed("measurement", {{"x", "m"}, {"y", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  lode::Tunables& block = h.tunables();
  auto measurement = h.input("measurement");
  const char* why = "";
  int accepted = 0;
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 1000; ++k) {
    for (std::size_t index = 0; index < 15; ++index) {
      const double value = index >= 12 ? 5.0 + (k % 2) : index >= 9 ? -5.0 - (k % 2) : 1.0 + 0.1 * (k % 3);
      accepted += block.set_tunable(index, value, why) ? 1 : 0;
    }
    (void)block.set_tunable(12, -10.0, why);
    measurement[0] = 1e-3 * std::sin(0.01 * k);
    h.step();
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  EXPECT_EQ(accepted, 15000);
}

}  // namespace
