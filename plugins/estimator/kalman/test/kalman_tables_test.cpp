// estimator.kalman against Tables IV and V of Kawato (2005 MS thesis): noise-free step
// responses of the propagated estimate x^-_{k+1} at 800 Hz, 100 um in X (Table IV, q_theta =
// 1e5) and 1 mrad in theta_z (Table V, q_x = q_y = 1e2), step at sample 80, p0 = 1e-8, x^-_0 = 0.
// The thesis's R_k came from the GLSDC and is not printed; the constant variances r = 2.2e-10 m^2
// (X) and 9.6e-9 rad^2 (theta) are fitted to the q = 1e2 row of Table IV and the q = 1e5 row of
// Table V.
//
//  1. Every row's step response equals an independent implementation of the thesis's Table III
//     recursion (the whole 9-state filter of eq. 4.35-4.41, not the block's per-axis split) to
//     1e-9 of the step. This is the check that fails when the block is detuned or broken.
//  2. The rows a constant r reproduces: rise time and overshoot against the printed values.
//  3. The two fastest rows of Table V, which it cannot: a deviation test that states why.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins {
namespace {

using lode::testing::BlockHarness;

constexpr double kRateHz = 800.0;
constexpr double kPeriodS = 1.0 / kRateHz;
constexpr double kP0 = 1e-8;                                  // thesis: P_0 = 1e-8 I
const std::array<double, 3> kR = {2.2e-10, 2.2e-10, 9.6e-9};  // fitted r: m^2, m^2, rad^2
constexpr int kStepSample = 80;  // the thesis's MATLAB demo steps at sample 80
constexpr int kSamples = 2400;   // 3 s: every row has settled
const Elements kPose{{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};

/// Table III of the thesis for the whole filter, written as printed: state x = [z; z'; z'']
/// with z = (X, Y, theta_z) (eq. 4.35), Phi and Upsilon of eq. 4.39, H = [I 0 0] (eq. 4.40),
/// Q_k = diag(q) (eq. 4.41), the short-form covariance update P+ = (I - K H) P-.
class TableIIIFilter {
 public:
  using Matrix9 = Eigen::Matrix<double, 9, 9>;
  using Vector9 = Eigen::Matrix<double, 9, 1>;

  TableIIIFilter(const std::array<double, 3>& q, const std::array<double, 3>& r, double p0, double t) {
    const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
    phi_.setZero();
    phi_.block<3, 3>(0, 0) = identity;
    phi_.block<3, 3>(0, 3) = t * identity;
    phi_.block<3, 3>(0, 6) = 0.5 * t * t * identity;
    phi_.block<3, 3>(3, 3) = identity;
    phi_.block<3, 3>(3, 6) = t * identity;
    phi_.block<3, 3>(6, 6) = identity;
    upsilon_ << (t * t * t / 6.0) * identity, (t * t / 2.0) * identity, t * identity;
    h_.setZero();
    h_.block<3, 3>(0, 0) = identity;
    q_ = Eigen::Vector3d(q[0], q[1], q[2]).asDiagonal();
    r_ = Eigen::Vector3d(r[0], r[1], r[2]).asDiagonal();
    x_.setZero();
    p_ = p0 * Matrix9::Identity();
  }

  /// One sample: gain, update, propagation. Returns the propagated position H x^-_{k+1}.
  Eigen::Vector3d step(const Eigen::Vector3d& y) {
    const Eigen::Matrix3d s = h_ * p_ * h_.transpose() + r_;
    const Eigen::Matrix<double, 9, 3> k = p_ * h_.transpose() * s.inverse();
    const Vector9 x_posterior = x_ + k * (y - h_ * x_);
    const Matrix9 p_posterior = (Matrix9::Identity() - k * h_) * p_;
    x_ = phi_ * x_posterior;
    p_ = phi_ * p_posterior * phi_.transpose() + upsilon_ * q_ * upsilon_.transpose();
    return h_ * x_;
  }

 private:
  Matrix9 phi_;
  Eigen::Matrix<double, 9, 3> upsilon_;
  Eigen::Matrix<double, 3, 9> h_;
  Eigen::Matrix3d q_, r_;
  Vector9 x_;
  Matrix9 p_;
};

/// One printed row: Q_k of the varied axis, 10-90 % rise time, overshoot.
struct PrintedRow {
  double q;
  double rise_time_s;
  double overshoot;
};

// Table IV (X, q_theta = 1e5); the q = 1 rise time is printed 0.1021 s, an OCR slip for 0.0121
// (its own bandwidth column: 1.8 / (2 pi 23.7 Hz) = 0.0121 s).
const std::vector<PrintedRow> kTableIV = {{1e-1, 0.0178, 0.324}, {1e0, 0.0121, 0.329}, {1e1, 0.0080, 0.336},
                                          {1e2, 0.0054, 0.344},  {1e3, 0.0033, 0.352}, {1e4, 0.0020, 0.400}};
constexpr double kTableIVOtherQ = 1e5;
constexpr double kTableIVStep = 100e-6;  // m
// Table V (theta, q_x = q_y = 1e2). The last two rows are the deviation test's.
const std::vector<PrintedRow> kTableV = {{1e2, 0.0100, 0.328}, {1e3, 0.0064, 0.321}, {1e4, 0.0039, 0.342},
                                         {1e5, 0.0025, 0.388}, {1e6, 0.0017, 0.444}, {1e7, 0.0010, 0.510}};
constexpr double kTableVOtherQ = 1e2;
constexpr double kTableVStep = 1e-3;  // rad

/// The row each constant r was fitted to (q = 1e2 in Table IV, 1e5 in Table V).
constexpr double kTableIVFitQ = 1e2;
constexpr double kTableVFitQ = 1e5;

struct StepResponse {
  std::vector<double> samples;      ///< the block's propagated output on the stepped axis
  double worst_reference_gap = NAN; ///< max |block - Table III| over every axis and sample
  double rise_time_s = NAN;         ///< 10-90 %, crossings not placed before the step sample
  double rise_time_from_pre_step_s = NAN;  ///< 10-90 %, the 10 % crossing may fall before it
  double overshoot = NAN;           ///< (peak - step) / step
  double final_value = NAN;
};

/// Time at which y first reaches `level` at or after the step sample, by linear interpolation
/// between consecutive samples. With `clip_to_step` a crossing is not placed before the step
/// sample: the pre-step sample belongs to the old steady state, and the estimate cannot respond
/// before the measurement that carries the step. Without it the 10 % crossing of a response
/// that already exceeds 10 % at the step sample is interpolated from the pre-step sample.
double crossing_time(const std::vector<double>& y, double level, bool clip_to_step) {
  for (std::size_t k = kStepSample; k < y.size(); ++k) {
    if (y[k] < level) continue;
    if (clip_to_step && k == static_cast<std::size_t>(kStepSample)) return kStepSample * kPeriodS;
    const double fraction = (level - y[k - 1]) / (y[k] - y[k - 1]);
    return (static_cast<double>(k - 1) + fraction) * kPeriodS;
  }
  return NAN;
}

/// The block in the thesis's set-up (constant r, p0 = 1e-8, x^-_0 = 0, propagated output), a
/// step of `amplitude` on `axis` at sample 80, run beside the Table III recursion on the same
/// samples.
StepResponse row_response(const std::array<double, 3>& q, std::size_t axis, double amplitude) {
  char params[512];
  std::snprintf(params, sizeof params,
                "motion: constant_acceleration\nq: [%.17g, %.17g, %.17g]\nr: [%.17g, %.17g, %.17g]\n"
                "p0: %.17g\noutput: predicted\ninitialize_from_first_measurement: false\n",
                q[0], q[1], q[2], kR[0], kR[1], kR[2], kP0);
  BlockHarness h("estimator.kalman", params, kRateHz);
  h.feed("measurement", kPose);
  StepResponse r;
  if (!h.configure() || !h.activate()) {
    ADD_FAILURE() << h.diagnostics();
    return r;
  }
  TableIIIFilter reference(q, kR, kP0, kPeriodS);
  auto y = h.input("measurement");
  auto pose = h.output("pose");
  r.worst_reference_gap = 0.0;
  for (int k = 0; k < kSamples; ++k) {
    Eigen::Vector3d measured = Eigen::Vector3d::Zero();
    measured(static_cast<Eigen::Index>(axis)) = k >= kStepSample ? amplitude : 0.0;
    for (std::size_t i = 0; i < 3; ++i) y[i] = measured(static_cast<Eigen::Index>(i));
    if (h.step() != StepStatus::ok) {
      ADD_FAILURE() << "fault: " << h.block().fault_reason();
      return r;
    }
    const Eigen::Vector3d expected = reference.step(measured);
    for (std::size_t i = 0; i < 3; ++i) {
      r.worst_reference_gap =
          std::max(r.worst_reference_gap, std::abs(pose[i] - expected(static_cast<Eigen::Index>(i))));
    }
    r.samples.push_back(pose[axis]);
  }
  const double peak = *std::max_element(r.samples.begin(), r.samples.end());
  r.final_value = r.samples.back();
  r.overshoot = (peak - amplitude) / amplitude;
  r.rise_time_s = crossing_time(r.samples, 0.9 * amplitude, true) - crossing_time(r.samples, 0.1 * amplitude, true);
  r.rise_time_from_pre_step_s =
      crossing_time(r.samples, 0.9 * amplitude, false) - crossing_time(r.samples, 0.1 * amplitude, false);
  return r;
}

/// Table IV varies q_x = q_y with q_theta fixed; Table V varies q_theta with q_x = q_y fixed.
std::array<double, 3> row_q(std::size_t axis, double q, double other_q) {
  return axis == 0 ? std::array<double, 3>{q, q, other_q} : std::array<double, 3>{other_q, other_q, q};
}

// The block against the Table III recursion: the two differ in the order of the state (per
// axis against eq. 4.35's stacking), in the covariance update (Joseph form against the short
// form; equal for the optimal gain) and in the arithmetic of the 3 x 3 inverse against a
// scalar division, so they agree to rounding, not bit for bit (measured: 2e-15 of the step at
// worst). 1e-9 leaves a wide margin over rounding and still fails on any change of the filter
// itself: q scaled by 1 + 1e-6 moves the output by 1.1-1.3e-7 of the step.
constexpr double kReferenceTolerance = 1e-9;

/// Overshoot within 10 % of the printed value. A constant-r tracker's overshoot rises
/// monotonically with q/r (32 -> 46 % over these rows), while the printed overshoots do not
/// (Table V: 32.8, 32.1, 34.2 %): the printed figures scatter by about 5 % around any smooth
/// curve in q (the 32.8 -> 32.1 dip against the model's +3.4 % rise), and 10 % is twice that.
constexpr double kOvershootTolerance = 0.10;

/// Rise time within 20 % of the printed value. One constant r per table is fitted at one row;
/// the other rows lie up to three decades of q away. A constant-acceleration tracker's
/// bandwidth goes as (q/r)^(1/6), so neighbouring rows (a decade of q apart) differ by a
/// factor 10^(1/6) = 1.47 or more (the printed ones by 1.47-1.65): +-20 % is about half that
/// spacing, the widest band in which a row still matches only its own q and not its
/// neighbour's. It also equals a factor 1.2^6 = 3 in the effective r, which is how well one
/// constant stands in for the thesis's per-sample R_k over five decades of q.
constexpr double kRiseTimeTolerance = 0.20;

/// The fitted rows match more tightly: half a unit of the printed last digit (0.05 ms) plus
/// what the two significant digits of r leave open (+-2.3 % in r is +-0.4 % in t_r, by the
/// (q/r)^(1/6) law).
double fitted_row_tolerance_s(double printed_s) { return 0.05e-3 + 0.004 * printed_s; }

void check_reproduced_rows(const char* title, const std::vector<PrintedRow>& rows, std::size_t axis,
                           double amplitude, double other_q, double fitted_q) {
  std::printf("\n%s (propagated output x^-_{k+1}, 800 Hz, step at sample 80)\n", title);
  std::printf("%9s | %21s | %7s | %10s | %19s | %6s | %s\n", "q", "t_r measured/printed", "dev", "t_r (A)*",
              "M_p meas/printed", "dev", "max |block - Table III| / step");
  for (const PrintedRow& row : rows) {
    const StepResponse r = row_response(row_q(axis, row.q, other_q), axis, amplitude);
    const double rise_dev = r.rise_time_s / row.rise_time_s - 1.0;
    const double overshoot_dev = r.overshoot / row.overshoot - 1.0;
    std::printf("%9.0e | %8.2f / %6.2f ms | %+6.1f%% | %7.2f ms | %6.1f / %5.1f %% | %+5.1f%% | %.1e\n", row.q,
                r.rise_time_s * 1e3, row.rise_time_s * 1e3, 100 * rise_dev, r.rise_time_from_pre_step_s * 1e3,
                100 * r.overshoot, 100 * row.overshoot, 100 * overshoot_dev, r.worst_reference_gap / amplitude);
    EXPECT_LE(r.worst_reference_gap, kReferenceTolerance * amplitude)
        << "q = " << row.q << ": the block's step response differs from the Table III recursion";
    EXPECT_NEAR(r.final_value, amplitude, 1e-6 * amplitude) << "q = " << row.q;
    EXPECT_NEAR(r.overshoot, row.overshoot, kOvershootTolerance * row.overshoot) << "q = " << row.q;
    EXPECT_NEAR(r.rise_time_s, row.rise_time_s, kRiseTimeTolerance * row.rise_time_s) << "q = " << row.q;
    if (row.q == fitted_q) {
      EXPECT_NEAR(r.rise_time_s, row.rise_time_s, fitted_row_tolerance_s(row.rise_time_s))
          << "q = " << row.q << " is the row r was fitted to";
    }
  }
  std::printf("* t_r (A): the 10 %% crossing also interpolated from the pre-step sample (not asserted)\n");
}

TEST(EstimatorKalman, TableIVStepResponseX) {
  check_reproduced_rows("Table IV: X, r = 2.2e-10 m^2", kTableIV, 0, kTableIVStep, kTableIVOtherQ, kTableIVFitQ);
}

TEST(EstimatorKalman, TableVStepResponseTheta) {
  const std::vector<PrintedRow> reproduced(kTableV.begin(), kTableV.begin() + 4);
  check_reproduced_rows("Table V: theta, r = 9.6e-9 rad^2 (q_theta <= 1e5)", reproduced, 2, kTableVStep,
                        kTableVOtherQ, kTableVFitQ);
}

/// Both crossings of the 10-90 % rise fall inside one sample interval: the first propagated
/// sample after the step (the output at the step sample) is already above 10 % and below 90 %,
/// and the next one is above 90 %.
bool rises_within_one_sample(const StepResponse& r, double amplitude) {
  const double first = r.samples[kStepSample];
  const double second = r.samples[kStepSample + 1];
  return first >= 0.1 * amplitude && first < 0.9 * amplitude && second >= 0.9 * amplitude;
}

TEST(EstimatorKalmanDeviation, TableVFastestRowsRiseWithinOneSample) {
  // Printed: 1.7 ms at q_theta = 1e6 and 1.0 ms at 1e7. Ours: 1.18 and 0.32 ms, 31 % and 68 %
  // short. Why: at these q the filter's 10-90 % rise is shorter than one sample period (1.25
  // ms): the first propagated sample after the step already exceeds 10 % and the 90 % crossing
  // falls within the next sample. The samples then do not resolve the rise: where between
  // them the two crossings are placed decides the figure. Placing the 10 % crossing at the
  // step sample (our convention) gives the shortest value; interpolating it from the pre-step
  // sample gives the longest; the printed times lie between the two. No constant r can move a
  // figure that the sampling does not determine, so these rows are not compared with 20 %.
  std::printf("\nTable V, the rows whose rise is shorter than one sample period (T = %.2f ms)\n", kPeriodS * 1e3);
  std::printf("%9s | %12s | %12s | %14s | %12s | %17s\n", "q_theta", "t_r printed", "t_r ours", "t_r (A) ours",
              "first/second", "M_p meas/printed");
  for (std::size_t i = 4; i < kTableV.size(); ++i) {
    const PrintedRow& row = kTableV[i];
    const StepResponse r = row_response(row_q(2, row.q, kTableVOtherQ), 2, kTableVStep);
    std::printf("%9.0e | %9.2f ms | %9.2f ms | %11.2f ms | %5.1f/%5.1f %% | %6.1f / %5.1f %%\n", row.q,
                row.rise_time_s * 1e3, r.rise_time_s * 1e3, r.rise_time_from_pre_step_s * 1e3,
                100 * r.samples[kStepSample] / kTableVStep, 100 * r.samples[kStepSample + 1] / kTableVStep,
                100 * r.overshoot, 100 * row.overshoot);
    EXPECT_LE(r.worst_reference_gap, kReferenceTolerance * kTableVStep) << "q = " << row.q;
    EXPECT_NEAR(r.final_value, kTableVStep, 1e-6 * kTableVStep) << "q = " << row.q;
    // The stated reason, sample by sample, and what it implies for the figures.
    EXPECT_TRUE(rises_within_one_sample(r, kTableVStep)) << "q = " << row.q;
    EXPECT_LT(r.rise_time_s, kPeriodS) << "q = " << row.q;
    EXPECT_LE(r.rise_time_s, row.rise_time_s) << "q = " << row.q;
    EXPECT_GE(r.rise_time_from_pre_step_s, row.rise_time_s) << "q = " << row.q;
    // The overshoot is a peak, which the sampling does resolve: it is held to the reproduced
    // rows' 10 % (q = 1e6: -9.0 %, 1e7: -9.8 %).
    EXPECT_NEAR(r.overshoot, row.overshoot, kOvershootTolerance * row.overshoot) << "q = " << row.q;
  }
  // The reason singles out these two rows: every reproduced row rises over two samples or more.
  for (std::size_t i = 0; i < 4; ++i) {
    const StepResponse r = row_response(row_q(2, kTableV[i].q, kTableVOtherQ), 2, kTableVStep);
    EXPECT_FALSE(rises_within_one_sample(r, kTableVStep)) << "Table V q = " << kTableV[i].q;
  }
  for (const PrintedRow& row : kTableIV) {
    const StepResponse r = row_response(row_q(0, row.q, kTableIVOtherQ), 0, kTableIVStep);
    EXPECT_FALSE(rises_within_one_sample(r, kTableIVStep)) << "Table IV q = " << row.q;
  }
}

}  // namespace
}  // namespace lode::plugins
