// estimator.kalman: steady-state gains and error poles, the time-varying R from the covariance
// input, the constant-velocity mode, ports, errors, and no allocation in step(). Tables IV and
// V of the thesis are in kalman_tables_test.cpp.
#include "kalman.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <numbers>
#include <string>
#include <vector>

#include "estimator/testing/constant_acceleration_axis.hpp"
#include "estimator/testing/harness_setup.hpp"
#include "estimator/testing/state_handover.hpp"
#include "estimator/testing/yaml_numbers.hpp"
#include "lode/sdk/testing/plugin_checks.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"


namespace lode::plugins {
namespace {

using lode::estimator_testing::ConstantAccelerationAxis;
using lode::estimator_testing::exact_list;
using lode::estimator_testing::hand_over;
using lode::estimator_testing::mean_nis;
using lode::estimator_testing::same_outputs;
using lode::estimator_testing::started;
using lode::testing::BlockHarness;
using lode::testing::member;
using lode::testing::numbers_of;

constexpr double kRateHz = 800.0;
constexpr double kPeriodS = 1.0 / kRateHz;
const Elements kPose{{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};


// --- 1. Steady-state gains --------------------------------------------------------------

TEST(EstimatorKalman, SteadyStateGainsMatchAnIndependentDareSolution) {
  BlockHarness h("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n", kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const auto& axes = member(d, "axes").elements();
  ASSERT_EQ(axes.size(), 3u);

  struct Expect {
    std::size_t axis;
    double gain[3];  // derived for the r fitted to Tables IV/V: [1, 1/s, 1/s^2]
    double omega0_rad_s;
  };
  const Expect expected[] = {{0, {0.197, 17.3, 760.0}, 88.0}, {2, {0.309, 45.5, 3360.0}, 148.0}};
  for (const Expect& e : expected) {
    const Json& ss = member(axes[e.axis], "steady_state");
    EXPECT_TRUE(member(ss, "converged").as_bool());
    const std::vector<double> gain = numbers_of(member(ss, "gain"));
    ASSERT_EQ(gain.size(), 3u);
    std::printf("axis %zu: K = [%.4f, %.3f, %.1f] (ref [%.3f, %.1f, %.0f]), %d Riccati iterations\n", e.axis,
                gain[0], gain[1], gain[2], e.gain[0], e.gain[1], e.gain[2],
                static_cast<int>(member(ss, "iterations").as_number()));
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(gain[static_cast<std::size_t>(i)], e.gain[i], 0.05 * e.gain[i]) << "axis " << e.axis << " K[" << i << "]";
    }
    // Error poles: inside the unit circle, at |ln z|/T ~ omega_0 = (q/r)^(1/6) (a 3rd-order
    // Butterworth-like pattern of a steady constant-acceleration tracker).
    for (const Json& pole : member(ss, "error_poles_z").elements()) {
      const double magnitude = member(pole, "abs").as_number();
      const double omega = member(pole, "continuous_rad_s").as_number();
      std::printf("  pole z = %.5f %+.5fj  |z| = %.5f  |ln z|/T = %.1f rad/s\n", member(pole, "re").as_number(),
                  member(pole, "im").as_number(), magnitude, omega);
      EXPECT_LT(magnitude, 1.0);
      EXPECT_NEAR(omega, e.omega0_rad_s, 0.10 * e.omega0_rad_s);
    }
  }
}

TEST(EstimatorKalman, RunningGainConvergesToDescribedGain) {
  // With output: filtered, x^+ = x^- + K (y - x^-): after the covariance has converged on zero
  // data, a one-sample measurement of delta shows K * delta on pose/velocity/acceleration.
  BlockHarness h("estimator.kalman", "q: [100]\nr: [2.2e-10]\noutput: filtered\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(started(h));
  const std::vector<double> gain =
      numbers_of(member(member(member(h.describe(), "axes").elements()[0], "steady_state"), "gain"));
  auto y = h.input("measurement");
  for (int k = 0; k < 4000; ++k) ASSERT_EQ(h.step(), StepStatus::ok);
  const double delta = 1e-6;
  y[0] = delta;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_NEAR(h.output("pose")[0] / delta, gain[0], 1e-9 * gain[0]);
  EXPECT_NEAR(h.output("velocity")[0] / delta, gain[1], 1e-9 * gain[1]);
  EXPECT_NEAR(h.output("acceleration")[0] / delta, gain[2], 1e-9 * gain[2]);
  EXPECT_NEAR(h.output("innovation")[0], delta, 1e-20);
}

// --- 2. Time-varying R from the covariance input -----------------------------------------

/// K[0] of the converged filter (output: filtered) at a diagonal R fed through `covariance`.
double position_gain_with_covariance(double variance, double r_param) {
  BlockHarness h("estimator.kalman", "q: [100, 100, 1e5]\nr: " + exact_list({r_param}) + "\noutput: filtered\n",
                 kRateHz);
  h.feed("measurement", kPose);
  Elements cov_elements;
  for (const char* n : {"xx", "xy", "xth", "yx", "yy", "yth", "thx", "thy", "thth"}) cov_elements.push_back({n, "m^2"});
  h.feed("covariance", cov_elements);
  EXPECT_TRUE(h.configure()) << h.diagnostics();
  EXPECT_TRUE(h.activate());
  auto y = h.input("measurement");
  auto cov = h.input("covariance");
  for (std::size_t i = 0; i < 9; ++i) cov[i] = 3e-9;  // off-diagonal: must be ignored
  for (std::size_t i = 0; i < 3; ++i) cov[i * 3 + i] = variance;
  for (int k = 0; k < 4000; ++k) EXPECT_EQ(h.step(), StepStatus::ok);
  y[0] = 1e-6;
  EXPECT_EQ(h.step(), StepStatus::ok);
  return h.output("pose")[0] / 1e-6;
}

TEST(EstimatorKalman, CovarianceInputSetsR) {
  // r given too (5e-9): the connected covariance input takes precedence.
  const double k_small_r = position_gain_with_covariance(2.2e-10, 5e-9);
  const double k_large_r = position_gain_with_covariance(2.2e-8, 5e-9);
  std::printf("K[0] with R = 2.2e-10: %.4f, with R = 2.2e-8: %.4f\n", k_small_r, k_large_r);
  EXPECT_NEAR(k_small_r, 0.197, 0.05 * 0.197) << "the diagonal of R_k is used, off-diagonals and r ignored";
  EXPECT_LT(k_large_r, 0.6 * k_small_r) << "larger R must give a smaller gain";
}

TEST(EstimatorKalman, TimeVaryingRChangesGainWithinOneRun) {
  BlockHarness h("estimator.kalman", "q: [100]\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  h.feed("covariance", {{"xx", "m^2"}});
  ASSERT_TRUE(started(h));
  auto y = h.input("measurement");
  auto cov = h.input("covariance");
  auto innovation = h.output("innovation");
  auto pose = h.output("pose");
  // A sine measurement; with small R the estimate follows it closely, with large R it lags:
  // compare the RMS innovation over the last second of each phase.
  auto phase = [&](double variance, int start) {
    cov[0] = variance;
    double sum = 0.0;
    for (int k = start; k < start + 2400; ++k) {
      y[0] = 1e-4 * std::sin(2.0 * std::numbers::pi * 5.0 * k * kPeriodS);
      EXPECT_EQ(h.step(), StepStatus::ok);
      if (k >= start + 1600) sum += innovation[0] * innovation[0];
    }
    return std::sqrt(sum / 800.0);
  };
  const double rms_small = phase(2.2e-10, 0);
  const double rms_large = phase(2.2e-6, 2400);
  std::printf("RMS innovation, 5 Hz sine: R = 2.2e-10 -> %.3e m, R = 2.2e-6 -> %.3e m\n", rms_small, rms_large);
  EXPECT_GT(rms_large, 10.0 * rms_small);
  EXPECT_TRUE(std::isfinite(pose[0]));

  cov[0] = 0.0;
  EXPECT_EQ(h.step(), StepStatus::fault) << "R <= 0 is a fault";
  cov[0] = -1e-10;
  EXPECT_EQ(h.step(), StepStatus::fault);
}

// --- 3. Constant velocity -----------------------------------------------------------------

TEST(EstimatorKalman, ConstantVelocityTracksRampWithoutError) {
  for (const char* output : {"predicted", "filtered"}) {
    BlockHarness h("estimator.kalman",
                   std::string("motion: constant_velocity\nq: [10]\nr: [1e-10]\noutput: ") + output + "\n", kRateHz);
    h.feed("measurement", {{"x", "m"}});
    ASSERT_TRUE(started(h));
    EXPECT_THROW(h.output("acceleration"), std::out_of_range) << "no acceleration output in constant_velocity";
    auto y = h.input("measurement");
    auto pose = h.output("pose");
    auto velocity = h.output("velocity");
    const double start_m = 0.01;
    const double speed_m_s = 0.05;
    const bool predicted = std::string(output) == "predicted";
    double worst = 0.0;
    for (int k = 0; k < 2400; ++k) {
      y[0] = start_m + speed_m_s * k * kPeriodS;
      ASSERT_EQ(h.step(), StepStatus::ok);
      const int target = predicted ? k + 1 : k;  // x^-_{k+1} predicts y_{k+1}
      if (k >= 1600) worst = std::max(worst, std::abs(pose[0] - (start_m + speed_m_s * target * kPeriodS)));
    }
    std::printf("constant velocity, %s: worst position error over the last second %.2e m, velocity %.9f m/s\n",
                output, worst, velocity[0]);
    EXPECT_LT(worst, 1e-12) << output;
    EXPECT_NEAR(velocity[0], speed_m_s, 1e-9) << output;
  }
}

// --- ports, initialisation, errors, faults, allocation ------------------------------------

TEST(EstimatorKalman, OutputElementsFollowTheMeasurement) {
  BlockHarness h("estimator.kalman", "q: [100, 100, 1e5]\nr: 1e-10\n", kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Elements& pose = h.output_elements("pose");
  const Elements& velocity = h.output_elements("velocity");
  const Elements& acceleration = h.output_elements("acceleration");
  const Elements& innovation = h.output_elements("innovation");
  ASSERT_EQ(pose.size(), 3u);
  ASSERT_EQ(velocity.size(), 3u);
  ASSERT_EQ(acceleration.size(), 3u);
  ASSERT_EQ(innovation.size(), 3u);
  EXPECT_EQ(pose[2].name, "theta_z");
  EXPECT_EQ(pose[2].unit, "rad");
  EXPECT_EQ(velocity[0].name, "x_dot");
  EXPECT_EQ(velocity[0].unit, "m/s");
  EXPECT_EQ(acceleration[2].name, "theta_z_ddot");
  EXPECT_EQ(acceleration[2].unit, "rad/s^2");
  EXPECT_EQ(innovation[1].name, "y");
  EXPECT_EQ(innovation[1].unit, "m");
}

TEST(EstimatorKalman, InitializeFromFirstMeasurementRemovesStartTransient) {
  auto worst_error = [](bool from_first) {
    BlockHarness h("estimator.kalman",
                   std::string("q: [100]\nr: [2.2e-10]\ninitialize_from_first_measurement: ") +
                       (from_first ? "true" : "false") + "\n",
                   kRateHz);
    h.feed("measurement", {{"x", "m"}});
    EXPECT_TRUE(h.configure()) << h.diagnostics();
    EXPECT_TRUE(h.activate());
    auto y = h.input("measurement");
    auto pose = h.output("pose");
    double worst = 0.0;
    for (int k = 0; k < 800; ++k) {
      y[0] = 5e-3;  // a stage resting 5 mm from the origin
      EXPECT_EQ(h.step(), StepStatus::ok);
      worst = std::max(worst, std::abs(pose[0] - 5e-3));
    }
    return worst;
  };
  const double with_init = worst_error(true);
  const double thesis = worst_error(false);
  std::printf("resting at 5 mm: worst error %.2e m initialised from y_0, %.2e m from x_0 = 0\n", with_init, thesis);
  EXPECT_LT(with_init, 1e-15);
  // From x^-_0 = 0 the first gain is p0/(p0 + r) = 0.978, then the CA tracker overshoots:
  // ~0.1 mm of transient, ten times the stage's 10 um resolution.
  EXPECT_GT(thesis, 5e-5);
}

TEST(EstimatorKalman, MissingVarianceIsALocatedError) {
  BlockHarness h("estimator.kalman", "q: [100, 100, 1e5]\n", kRateHz);
  h.feed("measurement", kPose);
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("blocks.dut.r"), std::string::npos) << h.diagnostics();
  EXPECT_NE(h.diagnostics().find("covariance"), std::string::npos) << h.diagnostics();
}

TEST(EstimatorKalman, BadParametersAreLocatedErrors) {
  struct Case {
    const char* yaml;
    const char* field;
  };
  const Case cases[] = {
      {"q: [100, 100]\nr: 1e-10\n", "blocks.dut.q"},
      {"q: [100, -1, 1]\nr: 1e-10\n", "blocks.dut.q"},
      {"q: 100\nr: [1e-10, 0, 1e-10]\n", "blocks.dut.r"},
      {"q: 100\nr: 1e-10\np0: [1, 2]\n", "blocks.dut.p0"},
      {"q: 100\nr: 1e-10\nmotion: constant_jerk\n", "blocks.dut.motion"},
      {"q: 100\nr: 1e-10\noutput: smoothed\n", "blocks.dut.output"},
      {"q: 100\nr: 1e-10\nqq: 1\n", "blocks.dut.qq"},
  };
  for (const Case& c : cases) {
    BlockHarness h("estimator.kalman", c.yaml, kRateHz);
    h.feed("measurement", kPose);
    EXPECT_FALSE(h.configure()) << c.yaml;
    EXPECT_NE(h.diagnostics().find(c.field), std::string::npos) << c.yaml << "\n" << h.diagnostics();
  }
  BlockHarness wrong_cov("estimator.kalman", "q: 100\n", kRateHz);
  wrong_cov.feed("measurement", kPose);
  wrong_cov.feed("covariance", {{"xx", "m^2"}, {"yy", "m^2"}, {"thth", "rad^2"}});
  EXPECT_FALSE(wrong_cov.configure());
  EXPECT_NE(wrong_cov.diagnostics().find("n*n = 9"), std::string::npos) << wrong_cov.diagnostics();
}

TEST(EstimatorKalman, NonFiniteMeasurementFaults) {
  BlockHarness h("estimator.kalman", "q: 100\nr: 2.2e-10\n", kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(started(h));
  auto y = h.input("measurement");
  ASSERT_EQ(h.step(), StepStatus::ok);
  const double before = h.output("pose")[0];
  y[1] = std::nan("");
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement");
  EXPECT_EQ(h.output("pose")[0], before) << "a fault leaves the outputs as they were";
  y[1] = 0.0;
  EXPECT_EQ(h.step(), StepStatus::ok);
}

TEST(EstimatorKalman, DescribeConstantVelocity) {
  BlockHarness h("estimator.kalman", "motion: constant_velocity\nq: [10]\nr: [1e-10]\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const Json& axis = member(d, "axes").elements().at(0);
  const auto& phi = member(axis, "phi").elements();
  ASSERT_EQ(phi.size(), 2u);
  EXPECT_EQ(numbers_of(phi[0]), (std::vector<double>{1.0, kPeriodS}));
  EXPECT_EQ(numbers_of(phi[1]), (std::vector<double>{0.0, 1.0}));
  EXPECT_EQ(numbers_of(member(axis, "upsilon")), (std::vector<double>{0.5 * kPeriodS * kPeriodS, kPeriodS}));
  EXPECT_EQ(member(axis, "q_unit").as_string(), "m^2/s^4");
  EXPECT_EQ(numbers_of(member(member(axis, "steady_state"), "gain")).size(), 2u);
}

TEST(EstimatorKalman, StepDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  for (const char* motion : {"constant_acceleration", "constant_velocity"}) {
    BlockHarness h("estimator.kalman", std::string("motion: ") + motion + "\nq: [100, 100, 1e5]\n", kRateHz);
    h.feed("measurement", kPose);
    Elements cov_elements;
    for (int i = 0; i < 9; ++i) cov_elements.push_back({"c" + std::to_string(i), "m^2"});
    h.feed("covariance", cov_elements);
    ASSERT_TRUE(started(h));
    auto y = h.input("measurement");
    auto cov = h.input("covariance");
    for (std::size_t i = 0; i < 3; ++i) cov[i * 3 + i] = 1e-10;
    const long before = static_cast<long>(lode::testing::allocation_count());
    for (int k = 0; k < 10000; ++k) {
      y[0] = 1e-4 * std::sin(0.01 * k);
      if (h.step() != StepStatus::ok) FAIL() << h.block().fault_reason();
    }
    EXPECT_EQ(static_cast<long>(lode::testing::allocation_count()) - before, 0) << motion;
  }
}

// --- estimator state (hot swap), innovation, invalid_measurement ---------------------------

/// Run `h` on a noisy sine for `steps` cycles (3 axes, y(k) also used later by the caller).
double sine_measurement(int k, std::size_t axis) { return 1e-4 * std::sin(0.01 * k + static_cast<double>(axis)) + 1e-7 * std::cos(1.3 * k); }

TEST(EstimatorKalmanState, LayoutNamesUnitsAndCovariance) {
  BlockHarness ca("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n", kRateHz);
  ca.feed("measurement", kPose);
  ASSERT_TRUE(ca.configure()) << ca.diagnostics();
  const StateLayout layout = ca.estimator().state_layout();
  const Elements expected{{"x", "m"},         {"x_dot", "m/s"},         {"x_ddot", "m/s^2"},
                          {"y", "m"},         {"y_dot", "m/s"},         {"y_ddot", "m/s^2"},
                          {"theta_z", "rad"}, {"theta_z_dot", "rad/s"}, {"theta_z_ddot", "rad/s^2"}};
  ASSERT_EQ(layout.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(layout.elements[i].name, expected[i].name);
    EXPECT_EQ(layout.elements[i].unit, expected[i].unit);
  }
  EXPECT_TRUE(layout.covariance);
  EXPECT_EQ(ca.estimator().innovation_size(), 3u);

  BlockHarness cv("estimator.kalman", "motion: constant_velocity\nq: 10\nr: 1e-10\n", kRateHz);
  cv.feed("measurement", {{"z", "m"}});
  ASSERT_TRUE(cv.configure()) << cv.diagnostics();
  const StateLayout cv_layout = cv.estimator().state_layout();
  ASSERT_EQ(cv_layout.size(), 2u);
  EXPECT_EQ(cv_layout.elements[1].name, "z_dot");
  EXPECT_EQ(cv_layout.elements[1].unit, "m/s");

  // Before any step: x^-_0 = 0 and P^-_0 = p0 I (block diagonal, cross-axis zero).
  ASSERT_TRUE(ca.activate());
  const auto e = lode::testing::export_state_of(ca.estimator());
  for (std::size_t i = 0; i < 9; ++i) {
    EXPECT_EQ(e.values[i], 0.0);
    for (std::size_t j = 0; j < 9; ++j) EXPECT_EQ(e.covariance[i * 9 + j], i == j ? 1e-8 : 0.0) << i << "," << j;
  }
  double residual[3], variance[3];
  EXPECT_FALSE(ca.estimator().innovation(residual, variance)) << "no update before the first step";
}

/// Export from a running instance, import into a fresh one, then both must produce the same
/// outputs bit for bit on the same inputs.
void check_export_import_bit_for_bit(const std::string& params, bool covariance_input) {
  SCOPED_TRACE(params);
  Elements cov_elements;
  for (int i = 0; i < 9; ++i) cov_elements.push_back({"c" + std::to_string(i), "m^2"});
  auto make = [&](BlockHarness& h) {
    h.feed("measurement", kPose);
    if (covariance_input) h.feed("covariance", cov_elements);
    ASSERT_TRUE(started(h));
  };
  BlockHarness a("estimator.kalman", params, kRateHz);
  BlockHarness b("estimator.kalman", params, kRateHz);
  make(a);
  make(b);
  auto feed = [&](BlockHarness& h, int k) {
    auto y = h.input("measurement");
    for (std::size_t i = 0; i < 3; ++i) y[i] = sine_measurement(k, i);
    if (covariance_input) {
      auto c = h.input("covariance");
      for (std::size_t i = 0; i < 3; ++i) c[i * 3 + i] = 1e-10 * (1.0 + 0.5 * std::sin(0.003 * k + i));
    }
  };
  for (int k = 0; k < 700; ++k) {
    feed(a, k);
    ASSERT_EQ(a.step(), StepStatus::ok);
  }
  EXPECT_TRUE(hand_over(a.estimator(), b.estimator()));
  const std::vector<std::string> ports = params.find("constant_velocity") != std::string::npos
                                             ? std::vector<std::string>{"pose", "velocity", "innovation"}
                                             : std::vector<std::string>{"pose", "velocity", "acceleration", "innovation"};
  for (int k = 700; k < 760; ++k) {
    feed(a, k);
    feed(b, k);
    ASSERT_EQ(a.step(), StepStatus::ok);
    ASSERT_EQ(b.step(), StepStatus::ok);
    ASSERT_TRUE(same_outputs(a, b, ports)) << "at k = " << k;
  }
}

TEST(EstimatorKalmanState, ExportImportReproducesTheNextStepsBitForBit) {
  check_export_import_bit_for_bit("q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n", false);
  check_export_import_bit_for_bit("q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\noutput: filtered\n", false);
  check_export_import_bit_for_bit("motion: constant_velocity\nq: [10, 10, 1e3]\nr: 1e-10\n", false);
  check_export_import_bit_for_bit("q: [100, 100, 1e5]\n", true);
}

TEST(EstimatorKalmanState, ImportClearsTheFirstMeasurementStart) {
  // A fresh instance would put its position on the first measurement; an imported state is
  // the prior, so the first innovation is y - x^- of the import, not 0.
  BlockHarness h("estimator.kalman", "q: 100\nr: 2.2e-10\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(started(h));
  const double values[3] = {1e-3, 0.0, 0.0};
  const double covariance[9] = {1e-10, 0, 0, 0, 1e-6, 0, 0, 0, 1e-2};
  const std::uint8_t present[3] = {1, 1, 1};
  h.estimator().import_state(values, covariance, present);
  h.input("measurement")[0] = 1.1e-3;
  ASSERT_EQ(h.step(), StepStatus::ok);
  EXPECT_NEAR(h.output("innovation")[0], 1e-4, 1e-15);
  double residual = 0.0, variance = 0.0;
  ASSERT_TRUE(h.estimator().innovation(&residual, &variance));
  EXPECT_EQ(residual, h.output("innovation")[0]);
  EXPECT_DOUBLE_EQ(variance, 1e-10 + 2.2e-10) << "S = H P^- H' + R of the imported P";
}

TEST(EstimatorKalmanState, PresentMaskKeepsInitialValuesAndP0) {
  BlockHarness a("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\np0: [1e-8, 2e-8, 3e-8]\n", kRateHz);
  BlockHarness b("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\np0: [1e-8, 2e-8, 3e-8]\n", kRateHz);
  for (BlockHarness* h : {&a, &b}) {
    h->feed("measurement", kPose);
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
  }
  for (int k = 0; k < 500; ++k) {
    auto y = a.input("measurement");
    for (std::size_t i = 0; i < 3; ++i) y[i] = sine_measurement(k, i);
    ASSERT_EQ(a.step(), StepStatus::ok);
  }
  auto e = lode::testing::export_state_of(a.estimator());
  // Mark the y axis velocity and everything of theta_z absent; give a cross-axis term too
  // (a UKF could): it must be dropped, the filter is block diagonal.
  std::vector<std::uint8_t> present(9, 1);
  present[4] = 0;
  present[6] = present[7] = present[8] = 0;
  e.covariance[0 * 9 + 3] = e.covariance[3 * 9 + 0] = 0.5 * std::sqrt(e.covariance[0] * e.covariance[30]);
  b.estimator().import_state(e.values.data(), e.covariance.data(), present.data());
  const auto got = lode::testing::export_state_of(b.estimator());
  const double p0[3] = {1e-8, 2e-8, 3e-8};
  for (std::size_t i = 0; i < 9; ++i) {
    const std::size_t axis = i / 3;
    EXPECT_EQ(got.values[i], present[i] ? e.values[i] : 0.0) << "element " << i;
    for (std::size_t j = 0; j < 9; ++j) {
      double expected = 0.0;
      if (axis == j / 3) {
        if (present[i] && present[j]) expected = e.covariance[i * 9 + j];
        else if (i == j) expected = p0[axis];
      }
      EXPECT_EQ(got.covariance[i * 9 + j], expected) << i << "," << j;
    }
  }
  EXPECT_TRUE(lode::testing::covariance_usable(got.covariance, 9));

  // Garbage in (non-symmetric, indefinite, NaN): still a symmetric positive definite P.
  std::vector<double> bad(81, 1.0);
  for (std::size_t i = 0; i < 9; ++i) bad[i * 9 + i] = -1.0;
  bad[1] = NAN;
  bad[3 * 9 + 4] = 7.0;
  const std::vector<std::uint8_t> all(9, 1);
  b.estimator().import_state(e.values.data(), bad.data(), all.data());
  const auto repaired = lode::testing::export_state_of(b.estimator());
  EXPECT_TRUE(lode::testing::covariance_usable(repaired.covariance, 9));
  for (std::size_t i = 0; i < 9; ++i) EXPECT_EQ(repaired.covariance[i * 9 + i], p0[i / 3]) << i;
  ASSERT_EQ(b.step(), StepStatus::ok);
}

TEST(EstimatorKalmanState, NisAveragesToTheNumberOfChannelsWithTheTrueR) {
  // White-noise jerk (q) and measurement noise (r) exactly as the filter assumes: the
  // normalised innovation squared sum nu_i^2 / S_ii is chi-square with m = 3 degrees of
  // freedom, mean 3 (Bar-Shalom, Li & Kirubarajan 2001, §5.4.2).
  const double q[3] = {100.0, 100.0, 1e5};
  const double r[3] = {2.2e-10, 2.2e-10, 9.6e-9};
  BlockHarness h("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n", kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(started(h));
  std::vector<ConstantAccelerationAxis> truth;
  for (std::size_t i = 0; i < 3; ++i) truth.emplace_back(kPeriodS, q[i], r[i], 42 + i, 1e-3);
  constexpr int kWarmup = 200;
  constexpr int kSteps = 20000;
  const double mean = mean_nis(h, h.input("measurement"), truth, kWarmup, kSteps);
  std::printf("kalman: mean NIS over %d steps = %.4f (m = 3)\n", kSteps, mean);
  EXPECT_GT(mean, 0.7 * 3);
  EXPECT_LT(mean, 1.3 * 3);
}

TEST(EstimatorKalmanInvalid, PredictCoastsTheAxisWithANaN) {
  const std::string params = "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\ninvalid_measurement: predict\n";
  BlockHarness h("estimator.kalman", params, kRateHz);
  BlockHarness reference("estimator.kalman", "q: [100, 100, 1e5]\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n", kRateHz);
  for (BlockHarness* b : {&h, &reference}) {
    b->feed("measurement", kPose);
    ASSERT_TRUE(b->configure()) << b->diagnostics();
    ASSERT_TRUE(b->activate());
  }
  auto run = [&](BlockHarness& b, int k, bool nan_on_y) {
    auto y = b.input("measurement");
    for (std::size_t i = 0; i < 3; ++i) y[i] = sine_measurement(k, i);
    if (nan_on_y) y[1] = std::nan("");
    return b.step();
  };
  for (int k = 0; k < 300; ++k) {
    ASSERT_EQ(run(h, k, false), StepStatus::ok);
    ASSERT_EQ(run(reference, k, false), StepStatus::ok);
  }
  const auto before = lode::testing::export_state_of(h.estimator());
  ASSERT_EQ(run(h, 300, true), StepStatus::ok) << h.block().fault_reason();
  ASSERT_EQ(run(reference, 300, false), StepStatus::ok);
  for (const char* port : {"pose", "velocity", "acceleration", "innovation"}) {
    for (std::size_t i = 0; i < 3; ++i) EXPECT_TRUE(std::isfinite(h.output(port)[i])) << port << i;
  }
  double nu[3], s[3];
  EXPECT_FALSE(h.estimator().innovation(nu, s)) << "a cycle with a coasting axis reports no innovation";
  EXPECT_EQ(h.output("innovation")[1], 0.0);
  // The other axes updated exactly as without the NaN.
  for (std::size_t i : {std::size_t{0}, std::size_t{2}}) {
    EXPECT_EQ(h.output("pose")[i], reference.output("pose")[i]);
    EXPECT_EQ(h.output("innovation")[i], reference.output("innovation")[i]);
  }
  // The y axis: time update only, x^-_{k+1} = Phi x^-_k, and P^- grew.
  const auto after = lode::testing::export_state_of(h.estimator());
  const double t = kPeriodS;
  const double* x = &before.values[3];
  EXPECT_DOUBLE_EQ(after.values[3], x[0] + t * x[1] + 0.5 * t * t * x[2]);
  EXPECT_DOUBLE_EQ(after.values[4], x[1] + t * x[2]);
  EXPECT_EQ(after.values[5], x[2]);
  EXPECT_EQ(h.output("pose")[1], after.values[3]) << "output: predicted";
  EXPECT_GT(after.covariance[3 * 9 + 3], before.covariance[3 * 9 + 3]);
  EXPECT_TRUE(lode::testing::covariance_usable(after.covariance, 9));
  // Back to valid data: the update resumes and the innovation is reported again.
  ASSERT_EQ(run(h, 301, false), StepStatus::ok);
  EXPECT_TRUE(h.estimator().innovation(nu, s));
  EXPECT_NE(h.output("innovation")[1], 0.0);

  // A non-positive or NaN R from the covariance input coasts too.
  BlockHarness c("estimator.kalman", "q: 100\ninvalid_measurement: predict\n", kRateHz);
  c.feed("measurement", {{"x", "m"}});
  c.feed("covariance", {{"xx", "m^2"}});
  ASSERT_TRUE(started(c));
  c.input("covariance")[0] = 1e-10;
  c.input("measurement")[0] = 1e-4;
  ASSERT_EQ(c.step(), StepStatus::ok);
  EXPECT_TRUE(c.estimator().innovation(nu, s));
  for (double bad : {0.0, -1e-10, std::nan("")}) {
    c.input("covariance")[0] = bad;
    EXPECT_EQ(c.step(), StepStatus::ok);
    EXPECT_FALSE(c.estimator().innovation(nu, s));
    EXPECT_TRUE(std::isfinite(c.output("pose")[0]));
  }
}

TEST(EstimatorKalmanInvalid, FaultModeIsTheDefaultAndUnchanged) {
  BlockHarness h("estimator.kalman", "q: 100\nr: 2.2e-10\ninvalid_measurement: fault\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(started(h));
  h.input("measurement")[0] = 1e-4;
  ASSERT_EQ(h.step(), StepStatus::ok);
  const auto before = lode::testing::export_state_of(h.estimator());
  h.input("measurement")[0] = std::nan("");
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement");
  double nu = 0.0, s = 0.0;
  EXPECT_FALSE(h.estimator().innovation(&nu, &s));
  const auto after = lode::testing::export_state_of(h.estimator());
  EXPECT_EQ(after.values, before.values) << "a fault leaves the state as it was";
  EXPECT_EQ(after.covariance, before.covariance);

  BlockHarness bad("estimator.kalman", "q: 100\nr: 2.2e-10\ninvalid_measurement: coast\n", kRateHz);
  bad.feed("measurement", {{"x", "m"}});
  EXPECT_FALSE(bad.configure());
  EXPECT_NE(bad.diagnostics().find("invalid_measurement"), std::string::npos) << bad.diagnostics();
}

TEST(EstimatorKalmanState, ExportImportInnovationDoNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  for (const char* motion : {"constant_acceleration", "constant_velocity"}) {
    BlockHarness h("estimator.kalman", std::string("motion: ") + motion + "\nq: [100, 100, 1e5]\nr: 1e-10\n", kRateHz);
    h.feed("measurement", kPose);
    ASSERT_TRUE(started(h));
    const StateLayout layout = h.estimator().state_layout();
    std::vector<double> values(layout.size()), covariance(layout.size() * layout.size());
    const std::vector<std::uint8_t> present(layout.size(), 1);
    double nu[3], s[3];
    auto y = h.input("measurement");
    const long before = static_cast<long>(lode::testing::allocation_count());
    for (int k = 0; k < 1000; ++k) {
      y[0] = 1e-4 * std::sin(0.01 * k);
      if (h.step() != StepStatus::ok) FAIL() << h.block().fault_reason();
      h.estimator().export_state(values.data(), covariance.data());
      h.estimator().import_state(values.data(), covariance.data(), present.data());
      (void)h.estimator().innovation(nu, s);
    }
    EXPECT_EQ(static_cast<long>(lode::testing::allocation_count()) - before, 0) << motion;
  }
}

}  // namespace
}  // namespace lode::plugins
