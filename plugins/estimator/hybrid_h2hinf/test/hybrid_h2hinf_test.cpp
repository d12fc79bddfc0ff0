// Tests of estimator.hybrid_h2hinf: the designs (Kalman gains against an independent DARE
// table, the H-infinity recursion against a closed form, feasibility, the bandwidths of the
// printed eq. 28 gains), and the block through the BlockHarness (d = 1 is the Kalman recursion
// bit for bit, the eq. 25 blend, set_mixing, stability refusals, faults, no allocation).
#include "hybrid_h2hinf.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <random>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "estimator/testing/constant_acceleration_axis.hpp"
#include "estimator/testing/harness_setup.hpp"
#include "estimator/testing/state_handover.hpp"
#include "lode/sdk/math/riccati.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"

namespace lode::plugins {
namespace {

using estimator_testing::ConstantAccelerationAxis;
using estimator_testing::hand_over;
using estimator_testing::mean_nis;
using estimator_testing::same_outputs;
using estimator_testing::started;
using hybrid::AxisModel;
using hybrid::HinfWeights;
using hybrid::Matrix3;
using hybrid::Vector3;
using lode::testing::BlockHarness;

constexpr double kRateHz = 800.0;  // assumed: the paper gives no sample rate
constexpr double kT = 1.0 / kRateHz;
constexpr double kR = 1e-6;  // eq. 26

const Elements kSixAxes = {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}, {"z", "m"}, {"theta_x", "rad"}, {"theta_y", "rad"}};
const Elements kOneAxis = {{"x", "m"}};

/// One configured block with `measurement` fed by the test.
struct Rig {
  Rig(const std::string& params, const Elements& measurement = kOneAxis)
      : h("estimator.hybrid_h2hinf", params, kRateHz), axes(measurement.size()) {
    h.feed("measurement", measurement);
    status = h.configure();
    if (status) status = h.activate();
    if (status) input = h.input("measurement");
  }
  HybridH2HinfEstimator& block() { return dynamic_cast<HybridH2HinfEstimator&>(h.block()); }
  StepStatus step(double y) {
    for (std::size_t i = 0; i < axes; ++i) input[i] = y;
    return h.step();
  }
  double pose(std::size_t i = 0) const { return h.output("pose")[i]; }
  BlockHarness h;
  std::size_t axes;
  Status status;
  std::span<double> input;  ///< looked up once: the harness's name lookup is not part of step()
};

Vector3 json_vector(const Json& j) {
  const auto& e = j.elements();
  return Vector3(e.at(0).as_number(), e.at(1).as_number(), e.at(2).as_number());
}

const Json& axis_json(const Json& describe, std::size_t i) { return describe.find("axes")->elements().at(i); }

/// The reference recursion of eq. 24 with a fixed gain, written out independently.
std::vector<double> reference_filter(const Vector3& k, const std::vector<double>& y) {
  Matrix3 phi;
  phi << 1, kT, kT * kT / 2, 0, 1, kT, 0, 0, 1;
  Vector3 x(y.front(), 0.0, 0.0);
  std::vector<double> out;
  for (double yk : y) {
    const Vector3 prior = phi * x;
    x = prior + k * (yk - prior(0));
    out.push_back(x(0));
  }
  return out;
}

std::vector<double> noisy_signal(int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-6);
  std::vector<double> y;
  for (int k = 0; k < n; ++k) {
    const double t = k * kT;
    y.push_back(20e-6 * (t > 0.1) + 3e-6 * std::sin(2 * std::numbers::pi * 50 * t) + noise(rng));
  }
  return y;
}

// ---------------------------------------------------------------------------------------------
// Designs

TEST(HybridDesign, KalmanGainsMatchAnIndependentDareSolution) {
  // An independent solution of the DARE with eqs. 23, 26, 27 at 800 Hz.
  struct Row {
    const char* axis;
    double q;
    Vector3 dare;     // the independent table
    Vector3 printed;  // eq. 28, entries repeated per axis filled in by symmetry
  };
  const Row rows[] = {{"x/y", 1e3, {0.0760, 2.403, 38.00}, {0.0531, 1.390, 37.42}},
                      {"theta_z", 1e5, {0.1566, 10.66, 363.0}, {0.1566, 9.47, 351.3}},
                      {"z/theta_x/theta_y", 1e2, {0.0524, 1.130, 12.17}, {0.0364, 0.752, 12.05}}};
  const AxisModel model = AxisModel::make(kT);
  for (const Row& row : rows) {
    const hybrid::KalmanDesign k = hybrid::design_kalman(model, row.q, kR);
    ASSERT_TRUE(k.ok) << k.error;
    std::printf("K^K %-18s measured (%.4f, %.3f, %.2f)  ref DARE (%.4f, %.3f, %.2f)  printed eq. 28 (%.4f, %.3f, %.2f)\n",
                row.axis, k.gain(0), k.gain(1), k.gain(2), row.dare(0), row.dare(1), row.dare(2), row.printed(0),
                row.printed(1), row.printed(2));
    for (int i = 0; i < 3; ++i) {
      // The table is rounded to 3-4 significant digits.
      EXPECT_NEAR(k.gain(i), row.dare(i), 6e-4 * row.dare(i) + 1e-4) << row.axis << " element " << i;
    }
  }
  // The one printed gain a single T reproduces: theta_z position gain 0.1566 at 800 Hz.
  EXPECT_NEAR(hybrid::design_kalman(model, 1e5, kR).gain(0), 0.1566, 5e-5);
}

TEST(HybridDesign, KalmanGainMatchesTheIteratedRiccatiRecursion) {
  // Independent of lode::math: iterate P <- Phi (P - P H'(H P H' + r)^-1 H P) Phi' + W.
  const AxisModel model = AxisModel::make(kT);
  const Matrix3 w = model.upsilon * 1e3 * model.upsilon.transpose();
  Matrix3 p = 1e-6 * Matrix3::Identity();
  Vector3 k = Vector3::Zero();
  for (int i = 0; i < 200000; ++i) {
    k = p.col(0) / (p(0, 0) + kR);
    Matrix3 ikh = Matrix3::Identity();
    ikh.col(0) -= k;
    p = model.phi * (ikh * p * ikh.transpose() + k * kR * k.transpose()) * model.phi.transpose() + w;
  }
  const Vector3 designed = hybrid::design_kalman(model, 1e3, kR).gain;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(designed(i), k(i), 1e-9 * std::abs(k(i)));
}

TEST(HybridDesign, HinfEqualsKalmanAtThetaZero) {
  const AxisModel model = AxisModel::make(kT);
  const hybrid::KalmanDesign k = hybrid::design_kalman(model, 1e3, kR);
  HinfWeights w;
  w.theta = 0.0;
  w.error_weight = Vector3(1, 1, 1);
  w.process_weight = 1e3;
  w.measurement_weight = kR;
  const hybrid::HinfDesign h = hybrid::design_hinf(model, w, k.prior_cov);
  ASSERT_TRUE(h.ok());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(h.gain(i), k.gain(i), 1e-9 * k.gain(i));
}

TEST(HybridDesign, HinfWithPositionWeightMatchesItsClosedForm) {
  // With S = diag(s, 0, 0) and H = [1 0 0], L = (I + (1/V - theta s) e1 e1' P)^-1, so the
  // recursion is the Kalman one with V' = V / (1 - theta s V), and by Sherman-Morrison
  // K^inf = (V'/V) K^K(V'). An independent check of design_hinf().
  const AxisModel model = AxisModel::make(kT);
  for (double theta : {1e5, 5e5, 8e5}) {
    HinfWeights w;
    w.theta = theta;
    w.error_weight = Vector3(1, 0, 0);
    w.process_weight = 1e3;
    w.measurement_weight = kR;
    const hybrid::HinfDesign h = hybrid::design_hinf(model, w, hybrid::design_kalman(model, 1e3, kR).prior_cov);
    ASSERT_TRUE(h.ok()) << theta;
    const double v_prime = kR / (1.0 - theta * kR);
    const Vector3 expected = (v_prime / kR) * hybrid::design_kalman(model, 1e3, v_prime).gain;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(h.gain(i), expected(i), 1e-7 * expected(i)) << theta << " " << i;
    if (theta == 5e5) {
      std::printf("K^inf (x, theta = 5e5, S = diag(1,0,0)) = (%.4f, %.3f, %.2f)\n", h.gain(0), h.gain(1), h.gain(2));
      EXPECT_NEAR(h.gain(0), 0.1360, 1e-4);
      EXPECT_NEAR(h.gain(1), 3.832, 1e-3);
      EXPECT_NEAR(h.gain(2), 53.97, 1e-2);
    }
  }
  // Feasible exactly while theta s V < 1.
  HinfWeights w;
  w.error_weight = Vector3(1, 0, 0);
  w.process_weight = 1e3;
  w.measurement_weight = kR;
  const double bound = hybrid::max_feasible_theta(model, w, hybrid::design_kalman(model, 1e3, kR).prior_cov);
  std::printf("largest feasible theta, S = diag(1,0,0): %.6g (closed form 1/(s V) = %.6g)\n", bound, 1.0 / kR);
  EXPECT_NEAR(bound, 1.0 / kR, 1e-3 / kR);
}

TEST(HybridDesign, PapersGammaTenIsInfeasibleWithUnitWeights) {
  // Derived here: S = I, W = Upsilon Q_k Upsilon', V = R_k, theta = 10 is infeasible on
  // every axis at 800 Hz because the acceleration variance is large.
  const AxisModel model = AxisModel::make(kT);
  for (double q : {1e3, 1e5, 1e2}) {
    HinfWeights w;
    w.theta = 10.0;
    w.error_weight = Vector3(1, 1, 1);
    w.process_weight = q;
    w.measurement_weight = kR;
    const Matrix3 start = hybrid::design_kalman(model, q, kR).prior_cov;
    const hybrid::HinfDesign h = hybrid::design_hinf(model, w, start);
    EXPECT_EQ(h.outcome, hybrid::HinfDesign::Outcome::infeasible) << "q = " << q;
    const double bound = hybrid::max_feasible_theta(model, w, start);
    std::printf("S = I, q = %g: theta = 10 infeasible after %d iterations, largest feasible theta %.4g\n", q,
                h.iterations, bound);
    EXPECT_LT(bound, 10.0);
    EXPECT_GT(bound, 0.0);
    w.theta = 0.99 * bound;
    EXPECT_TRUE(hybrid::design_hinf(model, w, start).ok());
  }
}

TEST(HybridDesign, PrintedEq28GainBandwidths) {
  // Computed independently: -3 dB bandwidth of the printed eq. 28 gains at 800 Hz: x/y ~9.8 Hz, theta_z
  // ~28.5 Hz, z/theta/psi ~7.1 Hz; x and z peak by +6 to +10 dB, theta_z by +3 to +4 dB.
  const AxisModel model = AxisModel::make(kT);
  struct Row {
    const char* axis;
    Vector3 gain;
    double bandwidth_hz;
    double peak_min_db, peak_max_db;
  };
  const Row rows[] = {{"x/y", {0.0531, 1.390, 37.42}, 9.8, 6.0, 10.0},
                      {"theta_z", {0.1566, 9.47, 351.3}, 28.5, 3.0, 4.0},
                      {"z", {0.0364, 0.752, 12.05}, 7.1, 6.0, 10.0}};
  for (const Row& row : rows) {
    const hybrid::PositionResponse r = hybrid::position_response(model, row.gain, kT);
    std::printf("printed %-8s bandwidth %.2f Hz (ref %.1f), peak %+.2f dB at %.2f Hz (ref %+.0f..%+.0f)\n", row.axis,
                r.bandwidth_hz, row.bandwidth_hz, r.peak_db, r.peak_hz, row.peak_min_db, row.peak_max_db);
    EXPECT_NEAR(r.bandwidth_hz, row.bandwidth_hz, 0.05 * row.bandwidth_hz) << row.axis;
    EXPECT_GE(r.peak_db, row.peak_min_db - 0.5) << row.axis;
    EXPECT_LE(r.peak_db, row.peak_max_db + 0.5) << row.axis;
  }
}

TEST(HybridDesign, ConvexBlendOfStableGainsCanBeUnstable) {
  // The paper's warning on eq. 25, on a concrete pair: each gain alone is stable, the
  // d = 0.5 blend is not. (Found by a random search; the Schur region is not convex.)
  const AxisModel model = AxisModel::make(kT);
  const Vector3 a(1.27, 438.0, 870000.0);
  const Vector3 b(0.376, 82.5, 11860.0);
  EXPECT_LT(hybrid::error_spectral_radius(model, a), 1.0);
  EXPECT_LT(hybrid::error_spectral_radius(model, b), 1.0);
  EXPECT_GT(hybrid::error_spectral_radius(model, hybrid::blend(0.5, a, b)), 1.0);
}

// ---------------------------------------------------------------------------------------------
// The block

const char* kPaperParams = R"(
q: [1.0e3, 1.0e3, 1.0e5, 1.0e2, 1.0e2, 1.0e2]
r: 1.0e-6
hinf_theta: 5.0e5
)";

TEST(HybridBlock, DescribeShowsBothGainsAndTheSweep) {
  Rig rig(kPaperParams, kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const Json j = rig.h.describe();
  const Vector3 kk = json_vector(*axis_json(j, 0).find("kalman_gain"));
  const Vector3 kh = json_vector(*axis_json(j, 0).find("hinf_gain"));
  EXPECT_NEAR(kk(0), 0.0760, 1e-4);
  EXPECT_NEAR(kh(0), 0.1360, 1e-4);
  const Json* design = axis_json(j, 2).find("hinf_design");
  ASSERT_NE(design, nullptr);
  EXPECT_NEAR(design->find("max_feasible_theta")->as_number(), 1e6, 1e3);
  // Observer stable for d in {0, 0.3, 0.8, 1} on every axis (the weights of Figs. 7-8).
  for (std::size_t i = 0; i < 6; ++i) {
    for (const Json& row : axis_json(j, i).find("mixing_sweep")->elements()) {
      EXPECT_LT(row.find("spectral_radius")->as_number(), 1.0)
          << axis_json(j, i).find("name")->as_string() << " d = " << row.find("d")->as_number();
    }
  }
  EXPECT_TRUE(j.find("stability")->find("every_d_stable")->as_bool());
}

TEST(HybridBlock, DEqualOneIsTheKalmanFilterExactly) {
  const std::vector<double> y = noisy_signal(4000, 7);
  const Vector3 kk = hybrid::design_kalman(AxisModel::make(kT), 1e3, kR).gain;
  const std::vector<double> expected = reference_filter(kk, y);
  // Two very different H-infinity designs: at d = 1 neither may leak into the output.
  Rig a("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 1.0");
  Rig b("q: 1.0e3\nr: 1.0e-6\nhinf_gain: [0.9, 300, 4.0e4]\nd: 1.0");
  ASSERT_TRUE(a.status) << a.h.diagnostics();
  ASSERT_TRUE(b.status) << b.h.diagnostics();
  for (std::size_t k = 0; k < y.size(); ++k) {
    ASSERT_EQ(a.step(y[k]), StepStatus::ok);
    ASSERT_EQ(b.step(y[k]), StepStatus::ok);
    ASSERT_EQ(a.pose(), expected[k]) << "cycle " << k;  // bit for bit
    ASSERT_EQ(b.pose(), expected[k]) << "cycle " << k;
  }
  // The same through set_mixing(): back to d = 1 after running at d = 0.
  Rig c("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.0");
  ASSERT_TRUE(c.status) << c.h.diagnostics();
  ASSERT_TRUE(c.block().set_mixing(1.0));
  for (std::size_t k = 0; k < y.size(); ++k) {
    c.step(y[k]);
    ASSERT_EQ(c.pose(), expected[k]) << "cycle " << k;
  }
}

TEST(HybridBlock, BlendFollowsEquation25) {
  const std::vector<double> y = noisy_signal(4000, 11);
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.3");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const Vector3 kk = rig.block().kalman_gain(0);
  const Vector3 kh = rig.block().hinf_gain(0);
  EXPECT_DOUBLE_EQ(rig.block().mixing(), 0.3);
  const std::vector<double> expected = reference_filter(0.3 * kk + 0.7 * kh, y);
  double worst = 0.0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    rig.step(y[k]);
    worst = std::max(worst, std::abs(rig.pose() - expected[k]));
  }
  EXPECT_LT(worst, 1e-15);  // rounding only (signal ~2e-5 m)
  // The d = 0 filter is the H-infinity filter.
  Rig zero("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0");
  const std::vector<double> hinf = reference_filter(kh, y);
  worst = 0.0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    zero.step(y[k]);
    worst = std::max(worst, std::abs(zero.pose() - hinf[k]));
  }
  EXPECT_LT(worst, 1e-15);
}

TEST(HybridBlock, TracksConstantAccelerationWithoutErrorForEveryD) {
  // The CA model (eq. 23) has a triple pole at z = 1: a parabola is followed with zero
  // steady-state error whatever the (stabilising) gain.
  for (double d : {0.0, 0.3, 0.8, 1.0}) {
    Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: " + std::to_string(d));
    ASSERT_TRUE(rig.status) << rig.h.diagnostics();
    double error = 0.0;
    for (int k = 0; k < 4000; ++k) {
      const double t = k * kT;
      rig.step(0.5 * 0.2 * t * t);  // 0.2 m/s^2
      error = rig.pose() - 0.5 * 0.2 * t * t;
    }
    EXPECT_LT(std::abs(error), 1e-12) << "d = " << d;
    EXPECT_NEAR(rig.h.output("acceleration")[0], 0.2, 1e-8);
    EXPECT_NEAR(rig.h.output("velocity")[0], 0.2 * 3999 * kT, 1e-9);
  }
}

TEST(HybridBlock, FiftyHertzAttenuationMatchesTheDesignedResponse) {
  // A 50 Hz measurement line (the paper's Hall-sensor interference) is attenuated by the
  // filter as its frequency response predicts; the Kalman gain (d = 1) cuts it more than the
  // wider H-infinity gain (d = 0).
  const AxisModel model = AxisModel::make(kT);
  double gain_at_50[2] = {0.0, 0.0};
  int slot = 0;
  for (double d : {1.0, 0.0}) {
    Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: " + std::to_string(d));
    double s = 0.0, c = 0.0;
    const int n = 8000;
    for (int k = 0; k < n + 4000; ++k) {
      const double phase = 2 * std::numbers::pi * 50.0 * k * kT;
      rig.step(1e-6 * std::sin(phase));
      if (k >= 4000) {
        s += rig.pose() * std::sin(phase);
        c += rig.pose() * std::cos(phase);
      }
    }
    const double amplitude = 2.0 * std::hypot(s, c) / n / 1e-6;
    const Vector3 k = hybrid::blend(d, rig.block().kalman_gain(0), rig.block().hinf_gain(0));
    // |G| at 50 Hz from the same transfer function describe() uses.
    using C = std::complex<double>;
    Matrix3 ikh = Matrix3::Identity();
    ikh.col(0) -= k;
    const Eigen::Matrix<C, 3, 3> a = (ikh * model.phi).cast<C>();
    const C z = std::polar(1.0, 2 * std::numbers::pi * 50.0 * kT);
    const Eigen::Matrix<C, 3, 1> x =
        (z * Eigen::Matrix<C, 3, 3>::Identity() - a).partialPivLu().solve(z * k.cast<C>());
    std::printf("d = %.0f: 50 Hz gain measured %.4f (%.1f dB), predicted %.4f\n", d, amplitude,
                20 * std::log10(amplitude), std::abs(x(0)));
    EXPECT_NEAR(amplitude, std::abs(x(0)), 2e-3);
    gain_at_50[slot++] = amplitude;
  }
  EXPECT_LT(gain_at_50[0], gain_at_50[1]);
}

TEST(HybridBlock, SetMixingChecksRangeAndStability) {
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 1.0");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  EXPECT_TRUE(rig.block().set_mixing(0.3));
  EXPECT_DOUBLE_EQ(rig.block().mixing(), 0.3);
  const Status above = rig.block().set_mixing(1.5);
  EXPECT_FALSE(above);
  EXPECT_NE(above.message().find("[0, 1]"), std::string::npos) << above.message();
  EXPECT_FALSE(rig.block().set_mixing(std::nan("")));
  EXPECT_DOUBLE_EQ(rig.block().mixing(), 0.3);  // unchanged

  // Injected gains whose midpoint is unstable: configure refuses d = 0.5, set_mixing too.
  const std::string pair = "q: 1.0e3\nr: 1.0e-6\nkalman_gain: [1.27, 438.0, 870000.0]\nhinf_gain: [0.376, 82.5, 11860.0]\n";
  Rig bad(pair + "d: 0.5");
  EXPECT_FALSE(bad.status);
  EXPECT_NE(bad.h.diagnostics().find("unstable"), std::string::npos) << bad.h.diagnostics();
  Rig good(pair + "d: 1.0");
  ASSERT_TRUE(good.status) << good.h.diagnostics();
  const Status refused = good.block().set_mixing(0.5);
  EXPECT_FALSE(refused);
  EXPECT_NE(refused.message().find("rho"), std::string::npos) << refused.message();
  EXPECT_DOUBLE_EQ(good.block().mixing(), 1.0);
  EXPECT_FALSE(good.h.describe().find("stability")->find("every_d_stable")->as_bool());
}

TEST(HybridBlock, MixingChangesWhileRunningOnAnotherThread) {
  // set_mixing() from a non-RT thread while step() runs: d is read once per cycle.
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 1.0");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  std::atomic<bool> done{false};
  std::thread changer([&] {
    int k = 0;
    while (!done.load()) (void)rig.block().set_mixing((k++ % 2) ? 0.3 : 0.8);
  });
  const std::vector<double> y = noisy_signal(20000, 3);
  bool finite = true;
  for (double v : y) {
    finite = finite && rig.step(v) == StepStatus::ok && std::isfinite(rig.pose());
  }
  done = true;
  changer.join();
  EXPECT_TRUE(finite);
  EXPECT_NEAR(rig.pose(), y.back(), 1e-5);
}

TEST(HybridBlock, ConfigurationErrorsAreReported) {
  const auto diagnostics = [](const std::string& params) {
    Rig rig(params, kSixAxes);
    EXPECT_FALSE(rig.status) << params;
    return rig.h.diagnostics();
  };
  // gamma = 10 of the paper with unit weights: refused with the largest feasible theta.
  const std::string infeasible = diagnostics("q: [1e3, 1e3, 1e5, 1e2, 1e2, 1e2]\nr: 1e-6\nhinf_theta: 10\n"
                                             "hinf_error_weight: [1, 1, 1]");
  std::printf("%s\n", infeasible.c_str());
  EXPECT_NE(infeasible.find("infeasible"), std::string::npos);
  EXPECT_NE(infeasible.find("largest feasible theta"), std::string::npos);
  EXPECT_NE(infeasible.find("theta_z"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: 1e-6\nhinf_theta: 5e5\nd: 1.2").find("[0, 1]"), std::string::npos);
  EXPECT_NE(diagnostics("q: [1e3, 1e3]\nr: 1e-6\nhinf_theta: 5e5").find("one per measured axis"), std::string::npos);
  EXPECT_NE(diagnostics("q: 0\nr: 1e-6\nhinf_theta: 5e5").find("> 0"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: -1\nhinf_theta: 5e5").find("R_k"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: 1e-6").find("hinf_theta"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: 1e-6\nhinf_gain: [0.1, 2, 30]\nhinf_theta: 5").find("not used"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: 1e-6\nhinf_theta: 5e5\nkalman_gain: [1, 2]").find("3 per axis"), std::string::npos);
  EXPECT_NE(diagnostics("q: 1e3\nr: 1e-6\nhinf_theta: 2.0e6").find("infeasible"), std::string::npos);
  // Exactly at the bound theta s V = 1 the recursion no longer contracts.
  const std::string at_bound = diagnostics("q: 1e3\nr: 1e-6\nhinf_theta: 1.0e6");
  EXPECT_NE(at_bound.find("diverges"), std::string::npos) << at_bound;
  EXPECT_NE(at_bound.find("largest feasible theta for this axis with error weight [1, 0, 0], w = 1000, v = 1e-06 is 999999"),
            std::string::npos) << at_bound;
}

TEST(HybridBlock, InjectedPaperGainsAreUsedAsGiven) {
  // "paper gain set": eq. 28, 3 per axis (entries repeated per axis filled in by symmetry).
  Rig rig("q: [1e3, 1e3, 1e5, 1e2, 1e2, 1e2]\nr: 1e-6\nhinf_theta: 5e5\n"
          "kalman_gain: [0.0531, 1.390, 37.42, 0.0531, 1.390, 37.42, 0.1566, 9.47, 351.3,\n"
          "              0.0364, 0.752, 12.05, 0.0364, 0.752, 12.05, 0.0364, 0.752, 12.05]",
          kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  EXPECT_EQ(rig.block().kalman_gain(2), Vector3(0.1566, 9.47, 351.3));
  EXPECT_EQ(rig.block().kalman_gain(5), Vector3(0.0364, 0.752, 12.05));
  EXPECT_NE(rig.h.describe().find("kalman_gain_source")->as_string().find("injected"), std::string::npos);
}

TEST(HybridBlock, NonFiniteMeasurementFaults) {
  Rig rig(kPaperParams, kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  EXPECT_EQ(rig.step(1e-6), StepStatus::ok);
  const double before = rig.pose(3);
  rig.h.input("measurement")[3] = std::nan("");
  EXPECT_EQ(rig.h.step(), StepStatus::fault);
  EXPECT_STREQ(rig.h.block().fault_reason(), "non-finite measurement");
  EXPECT_EQ(rig.pose(3), before);
}

TEST(HybridBlock, PredictedOutputIsOneStepAhead) {
  Rig filtered("q: 1e3\nr: 1e-6\nhinf_theta: 5e5\noutput: filtered");
  Rig predicted("q: 1e3\nr: 1e-6\nhinf_theta: 5e5\noutput: predicted");
  for (int k = 0; k < 100; ++k) {
    filtered.step(1e-3 * k * kT);
    predicted.step(1e-3 * k * kT);
  }
  const double p = filtered.pose(), v = filtered.h.output("velocity")[0], a = filtered.h.output("acceleration")[0];
  EXPECT_NEAR(predicted.pose(), p + v * kT + 0.5 * a * kT * kT, 1e-18);
}

TEST(HybridBlock, StepAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Rig rig(kPaperParams, kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  rig.block().set_mixing(0.8);
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) rig.step(1e-6 * std::sin(k * 0.1));
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

// ---- Runtime parameter `d` (lode set) ----

TEST(HybridTunables, ReportsDInZeroOne) {
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.7");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const std::vector<Tunable> t = rig.h.tunables().tunables();
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t[0].name, "d");
  EXPECT_EQ(t[0].unit, "1");
  EXPECT_EQ(t[0].min, 0.0);
  EXPECT_EQ(t[0].max, 1.0);
  EXPECT_FALSE(t[0].integer);
  EXPECT_DOUBLE_EQ(rig.h.tunables().tunable_value(0), 0.7);
}

TEST(HybridTunables, SetDTakesEffectAtTheNextStepWithoutResettingTheState) {
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 1.0");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const Vector3 kk = rig.block().kalman_gain(0);
  const Vector3 kh = rig.block().hinf_gain(0);
  const std::vector<double> y = noisy_signal(2000, 5);
  constexpr std::size_t kSwitch = 1000;
  constexpr double kNewD = 0.3;
  // Eq. 24 written out: gain K^K until kSwitch, then the eq. 25 blend, state carried over.
  Matrix3 phi;
  phi << 1, kT, kT * kT / 2, 0, 1, kT, 0, 0, 1;
  Vector3 x(y.front(), 0.0, 0.0);
  double worst = 0.0;
  double jump_at_switch = 0.0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    if (k == kSwitch) {
      const char* why = "";
      ASSERT_TRUE(rig.h.tunables().set_tunable(0, kNewD, why)) << why;
      EXPECT_DOUBLE_EQ(rig.h.tunables().tunable_value(0), kNewD);
    }
    const Vector3 gain = k < kSwitch ? kk : Vector3(kNewD * kk + (1.0 - kNewD) * kh);
    const Vector3 prior = phi * x;
    x = prior + gain * (y[k] - prior(0));
    const double previous = rig.pose();
    ASSERT_EQ(rig.step(y[k]), StepStatus::ok);
    worst = std::max(worst, std::abs(rig.pose() - x(0)));
    if (k == kSwitch) jump_at_switch = std::abs(rig.pose() - previous);
  }
  std::printf("d 1 -> 0.3 at cycle %zu: worst |pose - reference| = %.3g m, step at the switch %.3g m\n", kSwitch,
              worst, jump_at_switch);
  EXPECT_LT(worst, 1e-12);
  // The estimate moves by one innovation, never by a reset (noise std 1e-6 m in noisy_signal).
  EXPECT_LT(jump_at_switch, 1e-5);
}

TEST(HybridTunables, RefusedDChangesNothing) {
  const std::string pair = "q: 1.0e3\nr: 1.0e-6\nkalman_gain: [1.27, 438.0, 870000.0]\nhinf_gain: [0.376, 82.5, 11860.0]\n";
  Rig rig(pair + "d: 1.0");
  Rig twin(pair + "d: 1.0");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  ASSERT_TRUE(twin.status);
  const std::vector<double> y = noisy_signal(600, 9);
  for (std::size_t k = 0; k < y.size(); ++k) {
    if (k == 300) {
      const char* why = "";
      EXPECT_FALSE(rig.h.tunables().set_tunable(0, 0.5, why));
      EXPECT_NE(std::string(why).find("unstable"), std::string::npos) << why;
      why = "";
      EXPECT_FALSE(rig.h.tunables().set_tunable(0, std::nan(""), why));
      EXPECT_STRNE(why, "");
      why = "";
      EXPECT_FALSE(rig.h.tunables().set_tunable(7, 0.5, why));
      EXPECT_STRNE(why, "");
      EXPECT_DOUBLE_EQ(rig.h.tunables().tunable_value(0), 1.0);
    }
    rig.step(y[k]);
    twin.step(y[k]);
    ASSERT_EQ(rig.pose(), twin.pose()) << "cycle " << k;
  }
}

TEST(HybridTunables, SetTunableAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Rig rig(kPaperParams, kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  Tunables& block = rig.h.tunables();
  const char* why = "";
  int accepted = 0;
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 1000; ++k) {
    accepted += block.set_tunable(0, (k % 2) ? 0.2 : 0.9, why) ? 1 : 0;
    (void)block.set_tunable(0, 2.0, why);  // refused: a static reason, no message built
    rig.step(1e-6 * std::sin(k * 0.1));
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  EXPECT_EQ(accepted, 1000);
}

// ---- Estimator state (hot swap), innovation, invalid_measurement ----

const Elements kPose3 = {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};

TEST(HybridState, LayoutMatchesTheKalmanOneToOneAndStateCrossesBothWays) {
  const std::string q_r = "q: [1.0e3, 1.0e3, 1.0e5]\nr: 1.0e-6\n";
  BlockHarness hybrid_h("estimator.hybrid_h2hinf", q_r + "hinf_theta: 5.0e5\nd: 0.3\n", kRateHz);
  BlockHarness kalman_h("estimator.kalman", q_r + "output: filtered\n", kRateHz);  // as the hybrid's default
  for (BlockHarness* h : {&hybrid_h, &kalman_h}) {
    h->feed("measurement", kPose3);
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
  }
  const StateLayout from_hybrid = hybrid_h.estimator().state_layout();
  const StateLayout from_kalman = kalman_h.estimator().state_layout();
  ASSERT_EQ(from_hybrid.size(), 9u);
  ASSERT_EQ(from_hybrid.size(), from_kalman.size());
  for (std::size_t i = 0; i < from_hybrid.size(); ++i) {
    EXPECT_EQ(from_hybrid.elements[i].name, from_kalman.elements[i].name) << i;
    EXPECT_EQ(from_hybrid.elements[i].unit, from_kalman.elements[i].unit) << i;
  }
  EXPECT_EQ(from_hybrid.elements[2].name, "x_ddot");
  EXPECT_EQ(from_hybrid.elements[2].unit, "m/s^2");
  EXPECT_TRUE(from_hybrid.covariance);
  EXPECT_EQ(hybrid_h.estimator().innovation_size(), kalman_h.estimator().innovation_size());

  auto run = [](BlockHarness& h, int from, int to) {
    auto y = h.input("measurement");
    for (int k = from; k < to; ++k) {
      for (std::size_t i = 0; i < 3; ++i) y[i] = 1e-4 * std::sin(0.02 * k + static_cast<double>(i));
      ASSERT_EQ(h.step(), StepStatus::ok);
    }
  };
  const std::vector<std::uint8_t> present(9, 1);
  // kalman -> hybrid: the state arrives unchanged.
  run(kalman_h, 0, 400);
  const auto k_state = lode::testing::export_state_of(kalman_h.estimator());
  hybrid_h.estimator().import_state(k_state.values.data(), k_state.covariance.data(), present.data());
  EXPECT_EQ(lode::testing::export_state_of(hybrid_h.estimator()).values, k_state.values);
  // hybrid -> kalman: the state and the hybrid's steady covariance arrive unchanged.
  run(hybrid_h, 400, 800);
  const auto h_state = lode::testing::export_state_of(hybrid_h.estimator());
  EXPECT_TRUE(lode::testing::covariance_usable(h_state.covariance, 9));
  kalman_h.estimator().import_state(h_state.values.data(), h_state.covariance.data(), present.data());
  const auto k_after = lode::testing::export_state_of(kalman_h.estimator());
  EXPECT_EQ(k_after.values, h_state.values);
  EXPECT_EQ(k_after.covariance, h_state.covariance);
  // Both now hold the same prior x^-_k: the first innovation after the swap is the same number.
  run(kalman_h, 800, 801);
  run(hybrid_h, 800, 801);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(kalman_h.output("innovation")[i], hybrid_h.output("innovation")[i]) << i;
  // Then each follows its own gains; both keep tracking the 100 um sine (no swap transient).
  run(kalman_h, 801, 900);
  run(hybrid_h, 801, 900);
  for (std::size_t i = 0; i < 3; ++i) {
    const double y = 1e-4 * std::sin(0.02 * 899 + static_cast<double>(i));
    EXPECT_NEAR(kalman_h.output("pose")[i], y, 1e-5) << i;
    EXPECT_NEAR(hybrid_h.output("pose")[i], y, 1e-5) << i;
  }
}

TEST(HybridState, SteadyCovarianceSolvesTheLyapunovEquationAndIsTheDarePriorAtDOne) {
  const AxisModel model = AxisModel::make(kT);
  const double q = 1e3;
  const hybrid::KalmanDesign kalman = hybrid::design_kalman(model, q, kR);
  ASSERT_TRUE(kalman.ok) << kalman.error;
  Matrix3 p;
  ASSERT_TRUE(hybrid::blended_prior_covariance(model, kalman.gain, q, kR, p));
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      EXPECT_NEAR(p(a, b), kalman.prior_cov(a, b), 1e-8 * std::sqrt(kalman.prior_cov(a, a) * kalman.prior_cov(b, b)))
          << a << "," << b;
    }
  }
  // d = 0.3 on the block: P = A P A' + W with A = Phi (I - K H), W = Phi K r K' Phi' + Upsilon q Upsilon'.
  Rig rig("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.3");
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const Vector3 k = hybrid::blend(0.3, rig.block().kalman_gain(0), rig.block().hinf_gain(0));
  const Matrix3& s = rig.block().steady_covariance(0);
  Matrix3 i_kh = Matrix3::Identity();
  i_kh.col(0) -= k;
  const Matrix3 a = model.phi * i_kh;
  const Vector3 phi_k = model.phi * k;
  const Matrix3 w = phi_k * kR * phi_k.transpose() + model.upsilon * q * model.upsilon.transpose();
  const Matrix3 residual = s - a * s * a.transpose() - w;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) EXPECT_LE(std::abs(residual(i, j)), 1e-12 * std::sqrt(s(i, i) * s(j, j))) << i << "," << j;
  }
  EXPECT_EQ(Eigen::LLT<Matrix3>(s).info(), Eigen::Success);
  // The blend is suboptimal: its error covariance is larger than the Kalman filter's.
  EXPECT_GT(s(0, 0), kalman.prior_cov(0, 0));
  std::printf("hybrid d = 0.3: steady P^-(0,0) = %.4g m^2 vs Kalman %.4g m^2\n", s(0, 0), kalman.prior_cov(0, 0));

  // A new d at run time moves the exported covariance with it (at the next step).
  const double before = lode::testing::export_state_of(rig.h.estimator()).covariance[0];
  const char* why = "";
  ASSERT_TRUE(rig.h.tunables().set_tunable(0, 1.0, why)) << why;
  ASSERT_EQ(rig.step(0.0), StepStatus::ok);
  const double after = lode::testing::export_state_of(rig.h.estimator()).covariance[0];
  EXPECT_NE(after, before);
  EXPECT_NEAR(after, kalman.prior_cov(0, 0), 1e-8 * kalman.prior_cov(0, 0));
}

TEST(HybridState, ExportImportReproducesTheNextStepsBitForBit) {
  for (const char* extra : {"d: 0.3\noutput: filtered\n", "d: 0.8\noutput: predicted\n", "d: 1.0\n"}) {
    SCOPED_TRACE(extra);
    const std::string params = std::string(kPaperParams) + extra;
    BlockHarness a("estimator.hybrid_h2hinf", params, kRateHz);
    BlockHarness b("estimator.hybrid_h2hinf", params, kRateHz);
    for (BlockHarness* h : {&a, &b}) {
      h->feed("measurement", kSixAxes);
      ASSERT_TRUE(started(*h));
    }
    const std::vector<double> y = noisy_signal(900, 3);
    auto feed = [&](BlockHarness& h, int k) {
      auto in = h.input("measurement");
      for (std::size_t i = 0; i < 6; ++i) in[i] = y[static_cast<std::size_t>(k)] * (1.0 + 0.1 * static_cast<double>(i));
    };
    for (int k = 0; k < 800; ++k) {
      feed(a, k);
      ASSERT_EQ(a.step(), StepStatus::ok);
    }
    EXPECT_TRUE(hand_over(a.estimator(), b.estimator()));
    for (int k = 800; k < 900; ++k) {
      feed(a, k);
      feed(b, k);
      ASSERT_EQ(a.step(), StepStatus::ok);
      ASSERT_EQ(b.step(), StepStatus::ok);
      ASSERT_TRUE(same_outputs(a, b, {"pose", "velocity", "acceleration", "innovation"})) << "k " << k;
    }
  }
}

TEST(HybridState, PresentMaskKeepsInitialValuesAndTheCovarianceStaysPositiveDefinite) {
  Rig a("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.5", kPose3);
  Rig b("q: 1.0e3\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: 0.5", kPose3);
  ASSERT_TRUE(a.status) << a.h.diagnostics();
  ASSERT_TRUE(b.status) << b.h.diagnostics();
  for (int k = 0; k < 300; ++k) ASSERT_EQ(a.step(1e-4 * std::sin(0.03 * k)), StepStatus::ok);
  const auto e = lode::testing::export_state_of(a.h.estimator());
  std::vector<std::uint8_t> present(9, 1);
  present[1] = 0;  // x_dot
  present[6] = present[7] = present[8] = 0;  // theta_z, all of it
  std::vector<double> values = e.values;
  values[4] = NAN;  // a non-finite value counts as absent
  b.h.estimator().import_state(values.data(), nullptr, present.data());
  const auto got = lode::testing::export_state_of(b.h.estimator());
  for (std::size_t i = 0; i < 9; ++i) {
    const bool given = present[i] != 0 && i != 4;
    EXPECT_EQ(got.values[i], given ? e.values[i] : 0.0) << i;
  }
  EXPECT_EQ(got.covariance, e.covariance) << "the covariance is the steady one, whatever is imported";
  EXPECT_TRUE(lode::testing::covariance_usable(got.covariance, 9));
  // theta_z's position was absent: the next measurement places it (initialize_from_first_measurement).
  b.input[0] = b.input[1] = 0.0;
  b.input[2] = 5e-3;
  ASSERT_EQ(b.h.step(), StepStatus::ok);
  EXPECT_EQ(b.h.output("innovation")[2], 0.0);
  EXPECT_EQ(b.h.output("pose")[2], 5e-3);
}

TEST(HybridState, NisAveragesToTheNumberOfChannelsForEveryD) {
  // The steady covariance is the true prior error covariance of the blended filter on its
  // design model, so nu^2 / S is chi-square(1) per axis for any d, not only d = 1.
  const double q[3] = {1e3, 1e3, 1e5};
  for (double d : {1.0, 0.3, 0.0}) {
    char params[160];
    std::snprintf(params, sizeof params, "q: [1.0e3, 1.0e3, 1.0e5]\nr: 1.0e-6\nhinf_theta: 5.0e5\nd: %g\n", d);
    Rig rig(params, kPose3);
    ASSERT_TRUE(rig.status) << rig.h.diagnostics();
    std::vector<ConstantAccelerationAxis> truth;
    for (std::size_t i = 0; i < 3; ++i) truth.emplace_back(kT, q[i], kR, 100 + i, 2e-3);
    constexpr int kSteps = 20000;
    const double mean = mean_nis(rig.h, rig.input, truth, 200, kSteps);
    std::printf("hybrid d = %.1f: mean NIS over %d steps = %.4f (m = 3)\n", d, kSteps, mean);
    EXPECT_GT(mean, 0.7 * 3) << "d = " << d;
    EXPECT_LT(mean, 1.3 * 3) << "d = " << d;
  }
}

TEST(HybridInvalid, PredictCoastsTheAxisWithANaNAndFaultModeIsUnchanged) {
  Rig coast(std::string(kPaperParams) + "invalid_measurement: predict\n", kSixAxes);
  Rig reference(kPaperParams, kSixAxes);
  ASSERT_TRUE(coast.status) << coast.h.diagnostics();
  ASSERT_TRUE(reference.status) << reference.h.diagnostics();
  for (int k = 0; k < 200; ++k) {
    ASSERT_EQ(coast.step(1e-5 * std::sin(0.05 * k)), StepStatus::ok);
    ASSERT_EQ(reference.step(1e-5 * std::sin(0.05 * k)), StepStatus::ok);
  }
  const auto before = lode::testing::export_state_of(coast.h.estimator());
  for (std::size_t i = 0; i < 6; ++i) coast.input[i] = reference.input[i] = 2e-6;
  coast.input[3] = std::nan("");
  ASSERT_EQ(coast.h.step(), StepStatus::ok) << coast.h.block().fault_reason();
  ASSERT_EQ(reference.h.step(), StepStatus::ok);
  double nu[6], s[6];
  EXPECT_FALSE(coast.h.estimator().innovation(nu, s));
  for (const char* port : {"pose", "velocity", "acceleration", "innovation"}) {
    for (std::size_t i = 0; i < 6; ++i) {
      EXPECT_TRUE(std::isfinite(coast.h.output(port)[i])) << port << i;
      if (i != 3) {
        EXPECT_EQ(coast.h.output(port)[i], reference.h.output(port)[i]) << port << i;
      }
    }
  }
  // Axis 3 (z): x^+ = x^- (output: filtered), x^-_{k+1} = Phi x^-_k.
  const auto after = lode::testing::export_state_of(coast.h.estimator());
  EXPECT_EQ(coast.h.output("pose")[3], before.values[9]);
  const Vector3 x(before.values[9], before.values[10], before.values[11]);
  const Vector3 expected = AxisModel::make(kT).phi * x;
  for (int a = 0; a < 3; ++a) EXPECT_EQ(after.values[9 + static_cast<std::size_t>(a)], expected(a));
  ASSERT_EQ(coast.step(2e-6), StepStatus::ok);
  EXPECT_TRUE(coast.h.estimator().innovation(nu, s));

  // Fault mode: the fault leaves every axis exactly as it was.
  const auto ref_before = lode::testing::export_state_of(reference.h.estimator());
  reference.input[5] = std::nan("");
  EXPECT_EQ(reference.h.step(), StepStatus::fault);
  EXPECT_EQ(lode::testing::export_state_of(reference.h.estimator()).values, ref_before.values);
  EXPECT_FALSE(reference.h.estimator().innovation(nu, s));
}

TEST(HybridState, ExportImportInnovationAllocateNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Rig rig(kPaperParams, kSixAxes);
  ASSERT_TRUE(rig.status) << rig.h.diagnostics();
  const StateLayout layout = rig.h.estimator().state_layout();
  std::vector<double> values(layout.size()), covariance(layout.size() * layout.size());
  const std::vector<std::uint8_t> present(layout.size(), 1);
  double nu[6], s[6];
  const char* why = "";
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 2000; ++k) {
    if (k == 1000) (void)rig.h.tunables().set_tunable(0, 0.8, why);  // recomputes the steady covariance
    rig.step(1e-6 * std::sin(k * 0.1));
    rig.h.estimator().export_state(values.data(), covariance.data());
    rig.h.estimator().import_state(values.data(), covariance.data(), present.data());
    (void)rig.h.estimator().innovation(nu, s);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

}  // namespace
}  // namespace lode::plugins
