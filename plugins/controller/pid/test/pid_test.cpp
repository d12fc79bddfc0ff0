// controller.pid: the gains-to-recursion design against a parallel PID written out, eq. 35's
// coefficients literally (and their roots, spec §7.3), the clamp and its anti-windup, setpoint
// weights, choosing the axis by name, configuration errors and no allocation in step().
#include "pid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "lode/testing/allocation_counter.hpp"
#include "lode/testing/harness.hpp"

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

TEST(PidDesign, Eq35RootsAsTheSpecReadsThem) {
  // Denominator 1 - 1.604 z^-1 + 0.603 z^-2: roots 1.0025 and 0.6015 (spec §7.3);
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
  if (lode::testing::allocation_counting_available()) {
    EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  }
  h.input("measurement")[0] = NAN;
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement or reference");
}

}  // namespace
