// estimator.ekf_encoder: the Singer discretisation (eq. 9-10) against independent
// computations, the steady state of Fig. 6, the structured update against the textbook
// eq. 14-16, phase (in)variance of P, tracking of absolute position over
// many periods, initialisation, faults, configuration errors and no allocation in step().
// The paper-level tables are in tests/integration/seed001_test.cpp.
#include "ekf_encoder.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>

#include "estimator/testing/harness_setup.hpp"
#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/math/riccati.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins {
namespace {

using lode::estimator_testing::faults_and_holds;
using lode::estimator_testing::started;
using ekf_encoder::StateMatrix;
using ekf_encoder::StateVector;
using lode::testing::BlockHarness;

constexpr double kAlpha = 200.0 * std::numbers::pi;  // Table 1
constexpr double kSigma2 = 1e-5;                     // Table 1
constexpr double kT20 = 1.0 / 20000.0;
constexpr double kT100 = 1.0 / 100000.0;
constexpr double kPitch = 4e-6;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

const char* kModels = "head: {plugin: sensor.sincos_encoder, pitch_m: 4.0e-6, amplitude_v: 1.0}\n";

StateMatrix singer_a(double alpha) {
  StateMatrix a;
  a << 0, 1, 0,  //
      0, 0, 1,   //
      0, 0, -alpha;
  return a;
}

/// e^{M} by its Taylor series (fine for ||M|| <= ~2; every term of the entries we use has
/// one sign pattern, so there is no cancellation to speak of).
StateMatrix exp_series(const StateMatrix& m) {
  StateMatrix sum = StateMatrix::Identity();
  StateMatrix term = StateMatrix::Identity();
  for (int n = 1; n < 60; ++n) {
    term = (term * m / n).eval();
    sum += term;
  }
  return sum;
}

/// Van Loan's integral Q_d = int_0^T e^{As} G q G' e^{A's} ds with the white-noise PSD
/// q = 2 alpha sigma_m^2 (the reading under which eq. 10 is exact), by 10-point
/// Gauss-Legendre quadrature: exact to rounding for these smooth integrands over one period.
StateMatrix van_loan_quadrature(double alpha, double period, double sigma2) {
  static const std::array<double, 5> nodes{0.1488743389816312, 0.4333953941292472, 0.6794095682990244,
                                           0.8650633666889845, 0.9739065285171717};
  static const std::array<double, 5> weights{0.2955242247147529, 0.2692667193099963, 0.2190863625159820,
                                             0.1494513491505806, 0.0666713443086881};
  const double psd = 2.0 * alpha * sigma2;
  StateMatrix q = StateMatrix::Zero();
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    for (double sign : {-1.0, 1.0}) {
      const double s = 0.5 * period * (1.0 + sign * nodes[i]);
      const StateVector g = exp_series(singer_a(alpha) * s).col(2);  // e^{As} G, G = e3
      q += (0.5 * period * weights[i] * psd) * (g * g.transpose());
    }
  }
  return q;
}

double max_relative_difference(const StateMatrix& a, const StateMatrix& b) {
  double worst = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) worst = std::max(worst, std::abs(a(i, j) - b(i, j)) / std::abs(b(i, j)));
  return worst;
}

// --- 1. Discretisation (eq. 9, 10) -----------------------------------------------------------

TEST(EkfEncoderSinger, TransitionIsTheMatrixExponential) {
  for (double alpha_t : {1e-4, kAlpha * kT100, kAlpha * kT20, 0.3, 0.49999, 0.50001, 1.0, 2.0}) {
    const double period = alpha_t / kAlpha;
    const StateMatrix f = ekf_encoder::singer_transition(kAlpha, period);
    const StateMatrix reference = exp_series(singer_a(kAlpha) * period);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        EXPECT_NEAR(f(i, j), reference(i, j), 1e-14 * std::abs(reference(i, j)) + 1e-300)
            << "alpha T " << alpha_t << " (" << i << "," << j << ")";
  }
}

TEST(EkfEncoderSinger, ProcessNoiseEqualsVanLoanIntegral) {
  // Independent of eq. 10's algebra: the defining integral, for the series branch and the
  // closed-form branch.
  for (double alpha_t : {kAlpha * kT100, kAlpha * kT20, 0.2, 0.49, 0.51, 1.0, 1.5}) {
    const double period = alpha_t / kAlpha;
    const StateMatrix q = ekf_encoder::singer_process_noise(kAlpha, period, kSigma2);
    const StateMatrix reference = van_loan_quadrature(kAlpha, period, kSigma2);
    EXPECT_LT(max_relative_difference(q, reference), 1e-12) << "alpha T " << alpha_t;
  }
}

TEST(EkfEncoderSinger, PrintedFormulaLosesDigitsAtSmallAlphaT) {
  // Eq. 10 as printed keeps ~8 significant digits at 20 kHz and ~4 at 100 kHz;
  // the series is exact. At alpha T = 1 both are the same closed form.
  const auto difference = [](double period) {
    return max_relative_difference(ekf_encoder::singer_process_noise_as_printed(kAlpha, period, kSigma2),
                                   ekf_encoder::singer_process_noise(kAlpha, period, kSigma2));
  };
  const double at_20k = difference(kT20), at_100k = difference(kT100);
  std::printf("eq. 10 as printed vs exact: max relative difference %.2e at 20 kHz, %.2e at 100 kHz\n", at_20k,
              at_100k);
  EXPECT_LT(at_20k, 1e-6);
  EXPECT_LT(at_100k, 1e-2);
  EXPECT_GT(at_100k, at_20k);
  EXPECT_LT(difference(1.0 / kAlpha), 1e-15);  // the same closed form, up to operation order
}

TEST(EkfEncoderSinger, SmallAlphaTApproachesTheWhiteJerkLimit) {
  // For alpha T -> 0 the Singer Q tends to the white-acceleration-rate (constant
  // acceleration) model with PSD q = 2 alpha sigma_m^2: q T^5/20, q T^4/8, q T^3/6, q T^3/3,
  // q T^2/2, q T.
  const double period = 1e-7;
  const double q = 2 * kAlpha * kSigma2;
  const StateMatrix qd = ekf_encoder::singer_process_noise(kAlpha, period, kSigma2);
  const double t = period;
  EXPECT_NEAR(qd(0, 0) / (q * std::pow(t, 5) / 20), 1.0, 1e-4);
  EXPECT_NEAR(qd(0, 1) / (q * std::pow(t, 4) / 8), 1.0, 1e-4);
  EXPECT_NEAR(qd(0, 2) / (q * std::pow(t, 3) / 6), 1.0, 1e-4);
  EXPECT_NEAR(qd(1, 1) / (q * std::pow(t, 3) / 3), 1.0, 1e-4);
  EXPECT_NEAR(qd(1, 2) / (q * t * t / 2), 1.0, 1e-4);
  EXPECT_NEAR(qd(2, 2) / (q * t), 1.0, 1e-4);
  // Positive definite at the paper's rates.
  for (double p : {kT20, kT100}) {
    const Eigen::SelfAdjointEigenSolver<StateMatrix> eig(ekf_encoder::singer_process_noise(kAlpha, p, kSigma2));
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
  }
}

TEST(EkfEncoderSinger, AgreesWithTheSharedVanLoan) {
  // core/math's van_loan (matrix exponential of the 6 x 6 Van Loan matrix) with the PSD
  // 2 alpha sigma_m^2 gives the same F and Q_d as eq. 9-10.
  for (double period : {kT20, kT100}) {
    lode::math::Matrix a = singer_a(kAlpha);
    lode::math::Matrix g = lode::math::Matrix::Zero(3, 1);
    g(2, 0) = 1.0;
    const lode::math::Matrix qc = lode::math::Matrix::Constant(1, 1, 2.0 * kAlpha * kSigma2);
    const lode::math::DiscreteNoise shared = lode::math::van_loan(a, g, qc, period);
    const StateMatrix f = ekf_encoder::singer_transition(kAlpha, period);
    const StateMatrix q = ekf_encoder::singer_process_noise(kAlpha, period, kSigma2);
    const double q_difference = max_relative_difference(StateMatrix(shared.Qd), q);
    std::printf("core/math van_loan vs eq. 10 at %.0f kHz: max relative difference %.2e\n", 1e-3 / period,
                q_difference);
    EXPECT_LT(max_relative_difference(StateMatrix(shared.Ad).cwiseMax(1e-300), f.cwiseMax(1e-300)), 1e-12);
    // The 6 x 6 exponential carries q11 ~ qT^5/20 (2e-27 at 100 kHz) next to entries of
    // order 1, so it keeps ~8 digits there (measured 6e-16 at 20 kHz, 8e-9 at 100 kHz); the
    // series is exact (see ProcessNoiseEqualsVanLoanIntegral).
    EXPECT_LT(q_difference, 1e-7);
  }
}

// --- 2. Steady state (Fig. 6) ------------------------------------------------------------------

TEST(EkfEncoderSteadyState, Fig6PredictedSigma) {
  // Criterion 1 (seed001_test.cpp): a-posteriori sqrt(P) within 5 % of 1.7 nm / 2.6 um/s; an
  // independent computation gives 1.71 / 2.60 (a priori 1.81 / 2.7).
  const double r_eq = std::pow(8e-3 / (kTwoPi / kPitch * 1.0), 2);  // 8 mV / (2 pi f_s V)
  const StateMatrix p0 = StateVector(4e-8, 1e-4, 1e-2).cwiseAbs2().asDiagonal();
  const auto ss = ekf_encoder::steady_state(ekf_encoder::singer_transition(kAlpha, kT20),
                                            ekf_encoder::singer_process_noise(kAlpha, kT20, kSigma2), r_eq, p0);
  ASSERT_TRUE(ss.converged);
  const double x = std::sqrt(ss.posterior_cov(0, 0)), v = std::sqrt(ss.posterior_cov(1, 1));
  std::printf("steady state: sqrt P11 %.4f nm, sqrt P22 %.4f um/s (a priori %.4f nm, %.4f um/s), %d iterations\n",
              x * 1e9, v * 1e6, std::sqrt(ss.prior_cov(0, 0)) * 1e9, std::sqrt(ss.prior_cov(1, 1)) * 1e6,
              ss.iterations);
  EXPECT_NEAR(x / 1.7e-9, 1.0, 0.05);
  EXPECT_NEAR(v / 2.6e-6, 1.0, 0.05);
  EXPECT_NEAR(std::sqrt(ss.prior_cov(0, 0)) / 1.81e-9, 1.0, 0.02);
  EXPECT_NEAR(std::sqrt(ss.prior_cov(1, 1)) / 2.7e-6, 1.0, 0.02);
  // Stable error dynamics.
  for (const auto& z : ss.poles) EXPECT_LT(std::hypot(z[0], z[1]), 1.0);

  // The same steady state from core/math's DARE solver (a different algorithm).
  lode::math::Matrix c = lode::math::Matrix::Zero(1, 3);
  c(0, 0) = 1.0;
  const auto shared = lode::math::steady_state_kalman(
      ekf_encoder::singer_transition(kAlpha, kT20), c, ekf_encoder::singer_process_noise(kAlpha, kT20, kSigma2),
      lode::math::Matrix::Constant(1, 1, r_eq));
  ASSERT_TRUE(shared.has_value()) << shared.error();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(shared.value().P_post(i, i) / ss.posterior_cov(i, i), 1.0, 1e-8) << i;
    EXPECT_NEAR(shared.value().P_prior(i, i) / ss.prior_cov(i, i), 1.0, 1e-8) << i;
  }
}

TEST(EkfEncoderSteadyState, DescribeShowsTheDerivedQuantities) {
  BlockHarness h("estimator.ekf_encoder", "model: head\n", 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  ASSERT_NE(d.find("transition_F"), nullptr);
  ASSERT_NE(d.find("process_noise_Qd"), nullptr);
  EXPECT_LT(d.find("as_printed_max_relative_difference")->as_number(), 1e-6);
  const Json* steady = d.find("steady_state");
  ASSERT_NE(steady, nullptr);
  EXPECT_TRUE(steady->find("converged")->as_bool());
  EXPECT_NEAR(steady->find("equivalent_position_std_m")->as_number(), 5.093e-9, 0.001e-9);
  EXPECT_NEAR(steady->find("posterior_std")->elements()[0].as_number(), 1.706e-9, 0.005e-9);
  EXPECT_NEAR(steady->find("posterior_std")->elements()[1].as_number(), 2.600e-6, 0.005e-6);
  EXPECT_NEAR(d.find("alpha_T")->as_number(), 0.0314159, 1e-6);
}

// --- 3. The update is eq. 14-16 --------------------------------------------------------------

TEST(EkfEncoderFilter, StructuredUpdateEqualsTextbookJosephForm) {
  // The filter uses K = P e1 w', w = S^-1 h; check against full 3 x m matrices.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  const std::vector<double> variance{(7.5e-3) * (7.5e-3), (5e-3) * (5e-3)};  // unequal R
  const StateMatrix f = ekf_encoder::singer_transition(kAlpha, kT20);
  const StateMatrix q = ekf_encoder::singer_process_noise(kAlpha, kT20, kSigma2);
  ekf_encoder::Filter filter;
  filter.configure(f, q, variance, StateVector(4e-8, 1e-4, 1e-2));
  filter.reset(1.3e-6);
  const double w = kTwoPi / kPitch;
  for (int k = 0; k < 50; ++k) {
    if (k > 0) filter.predict();
    const StateVector x = filter.state();
    const StateMatrix p = filter.covariance();
    const double theta = w * x(0);
    const std::array<double, 2> predicted{std::sin(theta), std::cos(theta)};
    const std::array<double, 2> slope{w * std::cos(theta), -w * std::sin(theta)};
    const std::array<double, 2> z{predicted[0] + 0.01 * n01(rng), predicted[1] + 0.01 * n01(rng)};

    Eigen::Matrix<double, 2, 3> H = Eigen::Matrix<double, 2, 3>::Zero();
    H(0, 0) = slope[0];
    H(1, 0) = slope[1];
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
    R(0, 0) = variance[0];
    R(1, 1) = variance[1];
    const Eigen::Matrix<double, 3, 2> K = p * H.transpose() * (H * p * H.transpose() + R).inverse();  // 15
    const Eigen::Vector2d innovation(z[0] - predicted[0], z[1] - predicted[1]);
    const StateVector x_ref = x + K * innovation;                                                 // 14
    const StateMatrix ikh = StateMatrix::Identity() - K * H;
    const StateMatrix p_ref = ikh * p * ikh.transpose() + K * R * K.transpose();                 // 16

    ASSERT_TRUE(filter.update(z.data(), predicted.data(), slope.data()));
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(filter.state()(i), x_ref(i), 1e-10 * std::abs(x_ref(i)) + 1e-22) << k;
      for (int j = 0; j < 3; ++j)
        EXPECT_NEAR(filter.covariance()(i, j), p_ref(i, j), 1e-9 * std::sqrt(p_ref(i, i) * p_ref(j, j))) << k;
    }
  }
}

StateMatrix covariance_after(double position_m, const std::vector<double>& variance, double pitch, double volts,
                             int steps) {
  const StateMatrix f = ekf_encoder::singer_transition(kAlpha, kT20);
  const StateMatrix q = ekf_encoder::singer_process_noise(kAlpha, kT20, kSigma2);
  ekf_encoder::Filter filter;
  filter.configure(f, q, variance, StateVector(pitch / 100, 1e-4, 1e-2));
  filter.reset(position_m);
  const double w = kTwoPi / pitch;
  for (int k = 0; k < steps; ++k) {
    if (k > 0) filter.predict();
    const double theta = w * filter.state()(0);
    const std::array<double, 2> predicted{volts * std::sin(theta), volts * std::cos(theta)};
    const std::array<double, 2> slope{w * volts * std::cos(theta), -w * volts * std::sin(theta)};
    EXPECT_TRUE(filter.update(predicted.data(), predicted.data(), slope.data()));
  }
  return filter.covariance();
}

TEST(EkfEncoderFilter, CovarianceIsPhaseInvariantWithEqualChannelNoise) {
  // With R = r I, H'R^-1 H does not depend on the phase.
  const std::vector<double> equal{64e-6, 64e-6};
  const StateMatrix reference = covariance_after(0.0, equal, kPitch, 1.0, 2000);
  for (double x : {0.37e-6, 1.0e-6, 2.9e-6}) {
    const StateMatrix p = covariance_after(x, equal, kPitch, 1.0, 2000);
    EXPECT_LT(max_relative_difference(p, reference), 1e-9) << x;
  }
  EXPECT_NEAR(std::sqrt(reference(0, 0)), 1.706e-9, 0.005e-9);
}

TEST(EkfEncoderFilter, ExperimentNoiseMakesPPhaseDependent) {
  // Emulation of the experiment (Table 5): pitch 20 um, V = 5.45 V (read as peak), sine 7.5 mV,
  // cosine 5 mV: an independent computation gives EKF sqrt(P) 1.1-1.5 nm and 2.0-2.4 um/s
  // depending on the phase.
  const std::vector<double> unequal{7.5e-3 * 7.5e-3, 5e-3 * 5e-3};
  const double pitch = 20e-6;
  double lo_x = 1, hi_x = 0, lo_v = 1, hi_v = 0;
  for (int i = 0; i < 8; ++i) {
    const StateMatrix p = covariance_after(i * pitch / 16, unequal, pitch, 5.45, 4000);
    lo_x = std::min(lo_x, std::sqrt(p(0, 0))), hi_x = std::max(hi_x, std::sqrt(p(0, 0)));
    lo_v = std::min(lo_v, std::sqrt(p(1, 1))), hi_v = std::max(hi_v, std::sqrt(p(1, 1)));
  }
  std::printf("experiment emulation (5.45 V peak): sqrt P11 %.2f-%.2f nm (ref 1.1-1.5), sqrt P22 %.2f-%.2f um/s "
              "(ref 2.0-2.4)\n",
              lo_x * 1e9, hi_x * 1e9, lo_v * 1e6, hi_v * 1e6);
  EXPECT_GT(hi_x / lo_x, 1.1);  // phase-dependent
  EXPECT_GE(lo_x, 1.05e-9);
  EXPECT_LE(hi_x, 1.55e-9);
  EXPECT_GE(lo_v, 1.95e-6);
  EXPECT_LE(hi_v, 2.45e-6);
}

// --- 4. The block ---------------------------------------------------------------------------------

struct Tracking {
  double worst_position_error_m = 0;
  double worst_velocity_error_m_s = 0;
  double final_position_m = 0;
};

/// Noise-free signals of x(t) = x0 + v t + A sin(2 pi f t) through the block.
Tracking track(double x0, double velocity, double amplitude, double frequency, double seconds,
               const std::string& extra_params = "") {
  BlockHarness h("estimator.ekf_encoder", "model: head\n" + extra_params, 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  h.feed("initial", {{"x", "m"}, {"v", "m/s"}});
  EXPECT_TRUE(h.configure()) << h.diagnostics();
  EXPECT_TRUE(h.activate());
  Tracking out;
  const int n = static_cast<int>(seconds * 20000.0);
  for (int k = 0; k < n; ++k) {
    const double t = k * kT20;
    const double x = x0 + velocity * t + amplitude * std::sin(kTwoPi * frequency * t);
    const double v = velocity + amplitude * kTwoPi * frequency * std::cos(kTwoPi * frequency * t);
    h.input("signals")[0] = std::sin(kTwoPi * x / kPitch);
    h.input("signals")[1] = std::cos(kTwoPi * x / kPitch);
    h.input("initial")[0] = x0;  // a coarse decoder's first sample (exact here)
    EXPECT_EQ(h.step(), lode::StepStatus::ok);
    if (t >= 0.2) {
      out.worst_position_error_m = std::max(out.worst_position_error_m, std::abs(h.output("estimate")[0] - x));
      out.worst_velocity_error_m_s =
          std::max(out.worst_velocity_error_m_s, std::abs(h.output("estimate")[1] - v));
    }
    out.final_position_m = h.output("estimate")[0];
  }
  return out;
}

TEST(EkfEncoder, TracksAbsolutePositionOverHundredsOfPeriods) {
  // The 2 mm/s ramp crosses 500 periods in 1 s: the filter carries absolute position with no
  // unwrapping, so it must end 2 mm away, not a multiple of 4 um off.
  const Tracking r = track(5e-6, 2e-3, 0.0, 0.0, 1.0);
  std::printf("ramp, noise-free: worst position error %.3g m, velocity %.3g m/s, final %.9f mm\n",
              r.worst_position_error_m, r.worst_velocity_error_m_s, r.final_position_m * 1e3);
  EXPECT_LT(r.worst_position_error_m, 1e-12);
  EXPECT_LT(r.worst_velocity_error_m_s, 1e-9);
  EXPECT_NEAR(r.final_position_m, 5e-6 + 2e-3 * (19999 * kT20), 1e-12);
}

TEST(EkfEncoder, SinusoidLagIsSmallAndGrowsWithAcceleration) {
  // A sinusoid is not a Singer path: without noise the filter lags by an amount that scales
  // with the acceleration (2 pi f)^2 A. At 10 Hz / 1 um it stays below the noise-driven
  // 1.7 nm sigma (it is why Table 2's 10 Hz column is the worst: 1.67 nm); at 2 Hz it is 25
  // times smaller.
  const Tracking fast = track(0.0, 0.0, 1e-6, 10.0, 0.6);
  const Tracking slow = track(0.0, 0.0, 1e-6, 2.0, 1.2);
  std::printf("noise-free lag: 10 Hz 1 um worst %.3f nm, %.3f um/s; 2 Hz 1 um worst %.4f nm, %.4f um/s\n",
              fast.worst_position_error_m * 1e9, fast.worst_velocity_error_m_s * 1e6,
              slow.worst_position_error_m * 1e9, slow.worst_velocity_error_m_s * 1e6);
  EXPECT_LT(fast.worst_position_error_m, 1.0e-9);
  EXPECT_LT(fast.worst_velocity_error_m_s, 2.5e-6);
  EXPECT_LT(slow.worst_position_error_m, 0.05e-9);
  EXPECT_NEAR(fast.worst_position_error_m / slow.worst_position_error_m, 25.0, 5.0);
}

TEST(EkfEncoder, InitialInputSetsTheFirstPosition) {
  // Started 25.3 periods from the origin: without the coarse position the filter would
  // lock onto the wrong period; with it, it starts there.
  const Tracking r = track(25.3 * kPitch, 0.0, 0.0, 0.0, 0.25);
  EXPECT_NEAR(r.final_position_m, 25.3 * kPitch, 1e-12);

  // Without the input, initial_position_m plays its part.
  BlockHarness h("estimator.ekf_encoder", "model: head\ninitial_position_m: 1.0e-4\n", 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  ASSERT_TRUE(started(h));
  EXPECT_EQ(h.output("estimate")[0], 1e-4);
  EXPECT_EQ(h.output("std")[0], 4e-8);
  const double x = 1e-4 + 0.1e-6;
  h.input("signals")[0] = std::sin(kTwoPi * x / kPitch);
  h.input("signals")[1] = std::cos(kTwoPi * x / kPitch);
  for (int k = 0; k < 200; ++k) ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("estimate")[0], x, 1e-12);
  EXPECT_LT(h.output("std")[0], 4e-9);
}

TEST(EkfEncoder, PortsAndInnovation) {
  BlockHarness h("estimator.ekf_encoder", "model: head\n", 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  ASSERT_TRUE(started(h));
  const auto& estimate = h.output_elements("estimate");
  ASSERT_EQ(estimate.size(), 2u);
  EXPECT_EQ(estimate[0].unit, "m");
  EXPECT_EQ(estimate[1].unit, "m/s");
  EXPECT_EQ(h.output_elements("acceleration")[0].unit, "m/s^2");
  const auto& std_elements = h.output_elements("std");
  ASSERT_EQ(std_elements.size(), 3u);
  EXPECT_EQ(std_elements[2].name, "a_std");
  const auto& innovation = h.output_elements("innovation");
  ASSERT_EQ(innovation.size(), 2u);
  EXPECT_EQ(innovation[0].name, "sin");
  EXPECT_EQ(innovation[1].unit, "V");
  // First sample at x = 0 with 5 mV on the sine: the innovation is what h(0) misses.
  h.input("signals")[0] = 0.005;
  h.input("signals")[1] = 1.0;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_NEAR(h.output("innovation")[0], 0.005, 1e-15);
  EXPECT_NEAR(h.output("innovation")[1], 0.0, 1e-15);
  EXPECT_GT(h.output("estimate")[0], 0.0);  // pulled toward the measured phase
}

TEST(EkfEncoder, NonFiniteSignalFaults) {
  BlockHarness h("estimator.ekf_encoder", "model: head\n", 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  ASSERT_TRUE(started(h));
  h.input("signals")[0] = 0.0;
  h.input("signals")[1] = 1.0;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_TRUE(faults_and_holds(h, "signals", 1, NAN, "non-finite encoder signal", "estimate"));
}

TEST(EkfEncoder, ConfigurationErrorsAreLocated) {
  BlockHarness h("estimator.ekf_encoder",
                 "model: head\nacceleration_pole_rad_s: 0\nacceleration_variance_m2_s4: -1\n"
                 "noise_std_v: [0.008, 0.008, 0.008]\ninitial_velocity_std_m_s: 0\n",
                 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* key : {"acceleration_pole_rad_s", "acceleration_variance_m2_s4", "noise_std_v",
                          "initial_velocity_std_m_s"}) {
    EXPECT_NE(d.find(key), std::string::npos) << key << " not reported in:\n" << d;
  }

  BlockHarness unknown("estimator.ekf_encoder", "model: nothing\n", 20000.0, kModels);
  unknown.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  EXPECT_FALSE(unknown.configure());
  EXPECT_NE(unknown.diagnostics().find("nothing"), std::string::npos) << unknown.diagnostics();

  BlockHarness wrong_kind("estimator.ekf_encoder", "model: axis\n", 20000.0, "axis: {plugin: plant.encoder_stage}\n");
  wrong_kind.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  EXPECT_FALSE(wrong_kind.configure());

  BlockHarness bad_initial("estimator.ekf_encoder", "model: head\n", 20000.0, kModels);
  bad_initial.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  bad_initial.feed("initial", {{"count", "1"}});
  EXPECT_FALSE(bad_initial.configure());
  EXPECT_NE(bad_initial.diagnostics().find("initial"), std::string::npos) << bad_initial.diagnostics();
}

TEST(EkfEncoder, StepDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  BlockHarness h("estimator.ekf_encoder", "model: head\nnoise_std_v: [0.0075, 0.005]\n", 20000.0, kModels);
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  ASSERT_TRUE(started(h));
  auto in = h.input("signals");
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) {
    const double x = 1e-6 * std::sin(kTwoPi * 5 * k * kT20);
    in[0] = std::sin(kTwoPi * x / kPitch);
    in[1] = std::cos(kTwoPi * x / kPitch);
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

TEST(EkfEncoder, SizedUpdateGivesTheGenericResultsBitForBit) {
  // A sin/cos head (2 channels) runs the update sized at compile time; compile_time_sizes: false
  // the capacity-4 dynamic code. Noisy signals (fixed seed) of a 1 um, 5 Hz sine on a 1 mm/s
  // ramp, equal and unequal channel noise: the same output bits every cycle, and the sized
  // step() does not allocate.
  LODE_REQUIRE_ALLOCATION_COUNTING();
  for (const char* noise : {"", "noise_std_v: [0.0075, 0.005]\n"}) {
    SCOPED_TRACE(noise);
    BlockHarness sized("estimator.ekf_encoder", std::string("model: head\n") + noise, 20000.0, kModels);
    BlockHarness generic("estimator.ekf_encoder", std::string("model: head\ncompile_time_sizes: false\n") + noise,
                         20000.0, kModels);
    for (BlockHarness* h : {&sized, &generic}) {
      h->feed("signals", {{"sin", "V"}, {"cos", "V"}});
      ASSERT_TRUE(started(*h));
    }
    ASSERT_TRUE(dynamic_cast<EkfEncoder&>(sized.block()).filter().fixed_size());
    ASSERT_FALSE(dynamic_cast<EkfEncoder&>(generic.block()).filter().fixed_size());
    EXPECT_EQ(generic.describe().find("algebra")->as_string(), "generic (sizes chosen at configure)");
    std::mt19937_64 rng(7);
    std::normal_distribution<double> volts(0.0, 8e-3);
    auto sized_in = sized.input("signals");
    auto generic_in = generic.input("signals");
    std::size_t allocations = 0;
    for (std::size_t k = 0; k < 6000; ++k) {
      const double t = static_cast<double>(k) * kT20;
      const double x = 1e-3 * t + 1e-6 * std::sin(kTwoPi * 5 * t);
      const double y[2] = {std::sin(kTwoPi * x / kPitch) + volts(rng), std::cos(kTwoPi * x / kPitch) + volts(rng)};
      for (int c = 0; c < 2; ++c) sized_in[static_cast<std::size_t>(c)] = generic_in[static_cast<std::size_t>(c)] = y[c];
      allocations += lode::estimator_testing::allocations_during([&] { ASSERT_EQ(sized.step(), lode::StepStatus::ok); });
      ASSERT_EQ(generic.step(), lode::StepStatus::ok);
      ASSERT_TRUE(lode::estimator_testing::same_outputs(sized, generic, {"estimate", "acceleration", "std", "innovation"}, k));
    }
    EXPECT_EQ(allocations, 0u) << "the sized step() allocated";
  }
}

}  // namespace
}  // namespace lode::plugins
