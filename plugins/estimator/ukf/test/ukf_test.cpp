// estimator.ukf: the exact weights of eq. 21, equality with the Kalman filter on a linear
// model, agreement with an independent textbook UKF in long double on the Sensors 2016
// suspension (1e-6 relative), the float32 hazard (sums about the centre point stay within the
// 0.05 mm resolution, raw sums do not), and the block: wiring by name, describe(),
// configuration errors, faults and no allocation in step().
#include "ukf.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "estimator/testing/harness_setup.hpp"
#include "estimator/testing/state_handover.hpp"
#include "estimator/testing/suspension_estimator.hpp"
#include "hall_polynomial.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"

namespace {

using lode::estimator_testing::faults_and_holds;
using lode::estimator_testing::kHallDistanceNoise;
using lode::estimator_testing::started;
using lode::estimator_testing::suspension_estimator;
using lode::plugins::ukf::Sums;
using lode::plugins::ukf::UnscentedCore;
using lode::plugins::ukf::Weights;

constexpr double kDt = 0.5e-3;

TEST(UkfWeights, ExactAtThePapersParameters) {
  // alpha = 0.002, beta = 2, kappa = 0, L = 3 (eq. 21): lambda = -2.999988.
  const Weights w = Weights::make(3, 0.002, 2.0, 0.0);
  EXPECT_NEAR(w.lambda, -2.999988, 1e-12);
  EXPECT_NEAR(w.spread() / 1.2e-5, 1.0, 1e-9);
  EXPECT_NEAR(w.mean0 / -249999.0, 1.0, 1e-9);
  EXPECT_NEAR(w.cov0 / -249996.0, 1.0, 1e-9);
  EXPECT_NEAR(w.other / (250000.0 / 6.0), 1.0, 1e-9);
  EXPECT_NEAR(w.mean_sum(), 1.0, 1e-9);
  EXPECT_NEAR(std::sqrt(w.spread()), 0.003464, 1e-6);
  // The printed weights (x 1e5) agree after rounding: -2.499, -2.5, 0.416.
  EXPECT_NEAR(w.mean0 / 1e5, -2.499, 0.001);
  EXPECT_NEAR(w.cov0 / 1e5, -2.5, 0.001);
  EXPECT_NEAR(w.other / 1e5, 0.416, 0.001);
}

// --- the Sensors 2016 suspension, written out independently of plant.suspension -----------
// Euler eq. 33 with the mass, config/suspension_ukf.yaml's self-consistent plant.
struct Plant {
  double m = 6.0e-3, g = 9.81, a = 5.996e-9, b = 4.85e-5, decay = 165.6, gain = 61.61;
  template <typename S>
  void step(const S* x, double u, S* next) const {
    const S d = x[0];
    const S acc = S(g) - (S(a) / (d * d * d * d) + S(b) * x[2] / (d * d)) / S(m);
    next[0] = x[0] + S(kDt) * x[1];
    next[1] = x[1] + S(kDt) * acc;
    next[2] = x[2] + S(kDt) * (S(-decay) * x[2] + S(gain) * S(u));
  }
  [[nodiscard]] double hold_current(double d) const { return (m * g - a / std::pow(d, 4)) * d * d / b; }
};

/// A closed-loop benchmark trajectory (PD on the true state, reference sine 24-28 mm) and
/// noisy gap measurements (0.1 mm).
struct Benchmark {
  std::vector<double> u;     ///< u_{k-1} seen at cycle k
  std::vector<double> y;     ///< measured gap at cycle k
  std::vector<std::array<double, 3>> truth;
};

Benchmark make_benchmark(int cycles, unsigned seed = 7) {
  const Plant p;
  Benchmark b;
  std::array<double, 3> x{0.026, 0.0, p.hold_current(0.026)};
  double u = p.hold_current(0.026) * p.decay / p.gain;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-4);
  for (int k = 0; k < cycles; ++k) {
    b.truth.push_back(x);
    b.u.push_back(u);
    b.y.push_back(x[0] + noise(rng));
    const double ref = 0.026 + 0.002 * std::sin(2 * M_PI * 2.0 * k * kDt);
    const double hold = p.hold_current(ref) * p.decay / p.gain;
    u = std::clamp(hold + 800.0 * (x[0] - ref) + 19.0 * x[1], 0.0, 5.0);
    std::array<double, 3> next{};
    p.step(x.data(), u, next.data());
    x = next;
  }
  return b;
}

constexpr std::array<double, 3> kQ{5.6e-8 * kDt, 1.7e-8 * kDt, 7.71e-3 * kDt};  // per_second q x dt
constexpr double kR = 1.2e-7;
constexpr std::array<double, 3> kP0{1e-6, 1e-4, 1e-2};

template <typename S>
struct CoreRun {
  std::vector<std::array<double, 3>> x;
  bool ok = true;
};

/// `points_at_once`: the models given as callables that take every sigma point in one call
/// (as the block passes its plugins' evaluate_points() and propagate_points()), else one point
/// per call.
template <typename S>
CoreRun<S> run_core(const Benchmark& b, Sums sums, double alpha = 0.002, bool points_at_once = false) {
  using Core = UnscentedCore<S>;
  const Plant p;
  Core core;
  core.configure(3, 1, Weights::make(3, alpha, 2.0, 0.0), sums);
  typename Core::Vector x0(3);
  x0 << S(0.0265), S(0.0), S(b.truth[0][2]);
  typename Core::Matrix P0 = Core::Matrix::Zero(3, 3);
  typename Core::Matrix Q = Core::Matrix::Zero(3, 3);
  for (int i = 0; i < 3; ++i) {
    P0(i, i) = S(kP0[static_cast<std::size_t>(i)]);
    Q(i, i) = S(kQ[static_cast<std::size_t>(i)]);
  }
  typename Core::MMatrix R(1, 1);
  R(0, 0) = S(kR);
  core.set(x0, P0);
  CoreRun<S> run;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    const double u = b.u[k];
    bool ok = core.draw();
    typename Core::MVector y(1);
    y(0) = S(b.y[k]);
    if (points_at_once) {
      if (ok && k > 0)
        ok = core.predict(
            [&](const double* x, std::size_t count, double* next) {
              for (std::size_t i = 0; i < count; ++i) p.step(x + 3 * i, u, next + 3 * i);
            },
            Q);
      if (ok)
        ok = core.update(
            [](const double* x, std::size_t count, double* out) {
              for (std::size_t i = 0; i < count; ++i) out[i] = x[3 * i];
            },
            y, R);
    } else {
      if (ok && k > 0) ok = core.predict([&](const double* x, double* next) { p.step(x, u, next); }, Q);
      if (ok) ok = core.update([](const double* x, double* out) { out[0] = x[0]; }, y, R);
    }
    if (!ok || !core.x().allFinite()) {
      run.ok = false;
      break;
    }
    run.x.push_back({static_cast<double>(core.x()(0)), static_cast<double>(core.x()(1)),
                     static_cast<double>(core.x()(2))});
  }
  return run;
}

/// A textbook UKF (eq. 20-31 literally: raw weighted sums, points redrawn each cycle) in long
/// double, written without the core's code: the reference for 1e-6 relative agreement.
std::vector<std::array<double, 3>> run_reference(const Benchmark& b) {
  using LD = long double;
  using V = Eigen::Matrix<LD, 3, 1>;
  using M = Eigen::Matrix<LD, 3, 3>;
  const Plant p;
  const int L = 3;
  const LD alpha = 0.002L, beta = 2.0L, kappa = 0.0L;
  const LD lambda = alpha * alpha * (L + kappa) - L;
  std::array<LD, 7> wm{}, wc{};
  wm[0] = lambda / (L + lambda);
  wc[0] = wm[0] + (1 - alpha * alpha + beta);
  for (int i = 1; i < 7; ++i) wm[static_cast<std::size_t>(i)] = wc[static_cast<std::size_t>(i)] = 1 / (2 * (L + lambda));
  V x(0.0265L, 0.0L, static_cast<LD>(b.truth[0][2]));
  M P = M::Zero();
  M Q = M::Zero();
  for (int i = 0; i < 3; ++i) {
    P(i, i) = static_cast<LD>(kP0[static_cast<std::size_t>(i)]);
    Q(i, i) = static_cast<LD>(kQ[static_cast<std::size_t>(i)]);
  }
  std::vector<std::array<double, 3>> out;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    const M S = Eigen::LLT<M>((L + lambda) * P).matrixL();
    std::array<V, 7> chi;
    chi[0] = x;
    for (int i = 0; i < L; ++i) {
      chi[static_cast<std::size_t>(1 + i)] = x + S.col(i);
      chi[static_cast<std::size_t>(1 + L + i)] = x - S.col(i);
    }
    V xm = x;
    M Pm = P;
    if (k > 0) {
      for (auto& c : chi) {
        V next;
        p.step(c.data(), b.u[k], next.data());
        c = next;
      }
      xm.setZero();
      for (std::size_t i = 0; i < 7; ++i) xm += wm[i] * chi[i];
      Pm = Q;
      for (std::size_t i = 0; i < 7; ++i) Pm += wc[i] * (chi[i] - xm) * (chi[i] - xm).transpose();
    }
    LD ym = 0;
    for (std::size_t i = 0; i < 7; ++i) ym += wm[i] * chi[i](0);
    LD Pyy = static_cast<LD>(kR);
    V Pxy = V::Zero();
    for (std::size_t i = 0; i < 7; ++i) {
      Pyy += wc[i] * (chi[i](0) - ym) * (chi[i](0) - ym);
      Pxy += wc[i] * (chi[i] - xm) * (chi[i](0) - ym);
    }
    const V K = Pxy / Pyy;
    x = xm + K * (static_cast<LD>(b.y[k]) - ym);
    P = Pm - K * Pyy * K.transpose();
    out.push_back({static_cast<double>(x(0)), static_cast<double>(x(1)), static_cast<double>(x(2))});
  }
  return out;
}

TEST(UkfCore, MatchesAnIndependentLongDoubleUkfToOnePpm) {
  const Benchmark b = make_benchmark(4000);
  const CoreRun<double> ours = run_core<double>(b, Sums::about_centre);
  ASSERT_TRUE(ours.ok);
  const auto reference = run_reference(b);
  std::array<double, 3> scale{}, worst{};
  for (const auto& r : reference)
    for (std::size_t i = 0; i < 3; ++i) scale[i] = std::max(scale[i], std::abs(r[i]));
  for (std::size_t k = 0; k < reference.size(); ++k)
    for (std::size_t i = 0; i < 3; ++i)
      worst[i] = std::max(worst[i], std::abs(ours.x[k][i] - reference[k][i]) / scale[i]);
  std::printf("UKF vs long-double textbook UKF, worst |difference| / max|x|: gap %.2e, velocity %.2e, current %.2e\n",
              worst[0], worst[1], worst[2]);
  for (double w : worst) EXPECT_LT(w, 1e-6);
  // And it estimates: the gap error is far below the 0.1 mm measurement noise.
  double sum = 0.0;
  for (std::size_t k = 1000; k < b.truth.size(); ++k) sum += std::pow(ours.x[k][0] - b.truth[k][0], 2);
  const double rms = std::sqrt(sum / static_cast<double>(b.truth.size() - 1000));
  std::printf("UKF gap error rms %.2f um (measurement noise 100 um)\n", rms * 1e6);
  EXPECT_LT(rms, 30e-6);
}

TEST(UkfCore, ModelsTakingEveryPointInOneCallGiveTheSameBits) {
  // The block hands its models every sigma point in one call; the core must lay the points
  // out and read the results back exactly as it does one point at a time.
  const Benchmark b = make_benchmark(2000);
  for (const Sums sums : {Sums::about_centre, Sums::raw}) {
    const CoreRun<double> one = run_core<double>(b, sums);
    const CoreRun<double> all = run_core<double>(b, sums, 0.002, true);
    ASSERT_TRUE(one.ok && all.ok);
    ASSERT_EQ(one.x.size(), all.x.size());
    for (std::size_t k = 0; k < one.x.size(); ++k)
      for (std::size_t j = 0; j < 3; ++j)
        ASSERT_EQ(one.x[k][j], all.x[k][j]) << "cycle " << k << " state " << j << (sums == Sums::raw ? " (raw sums)" : "");
  }
}

TEST(UkfCore, Float32NeedsSumsAboutTheCentrePoint) {
  // In float (the STM32F4's FPU) the raw sums lose ~2.5e5 x 6e-8 of |x|; the
  // deviation form keeps the estimate within the 0.05 mm resolution of the double filter.
  const Benchmark b = make_benchmark(4000);
  const CoreRun<double> reference = run_core<double>(b, Sums::about_centre);
  const CoreRun<float> centred = run_core<float>(b, Sums::about_centre);
  const CoreRun<float> raw = run_core<float>(b, Sums::raw);
  ASSERT_TRUE(reference.ok);
  ASSERT_TRUE(centred.ok) << "float32 with sums about the centre point failed";
  double worst_centred = 0.0;
  for (std::size_t k = 0; k < reference.x.size(); ++k)
    worst_centred = std::max(worst_centred, std::abs(centred.x[k][0] - reference.x[k][0]));
  double worst_raw = 0.0;
  for (std::size_t k = 0; k < raw.x.size(); ++k)
    worst_raw = std::max(worst_raw, std::abs(raw.x[k][0] - reference.x[k][0]));
  std::printf("float32 worst gap deviation from the double UKF: about the centre %.3f um, raw sums %s%.1f um\n",
              worst_centred * 1e6, raw.ok ? "" : "(diverged after) ", worst_raw * 1e6);
  EXPECT_LT(worst_centred, 0.05e-3);
  EXPECT_TRUE(!raw.ok || worst_raw > 0.05e-3) << "the raw form should show the hazard";
}

/// On a linear model, the UKF against the Kalman filter: with redrawn points it is the Kalman
/// filter at any alpha; with the paper's eq. 25 (no redraw) it is the Kalman filter whose
/// update uses A P A' (without Q) in P_yy and P_xy. Returns the worst |difference|.
double linear_difference(double alpha, bool redraw) {
  Eigen::Matrix3d A;
  A << 1.0, 0.01, 0.0, -0.3, 0.98, 0.05, 0.0, 0.0, 0.9;
  const Eigen::Vector3d B(0.0, 0.0, 0.1);
  const Eigen::RowVector3d C(1.0, 0.5, 0.0);
  const Eigen::Matrix3d Q = Eigen::Vector3d(1e-4, 2e-4, 1e-3).asDiagonal();
  const double R = 0.01;
  UnscentedCore<double> core;
  core.configure(3, 1, Weights::make(3, alpha, 2.0, 0.0), Sums::about_centre, redraw);
  UnscentedCore<double>::Vector x0 = Eigen::Vector3d(1.0, -0.5, 0.2);
  UnscentedCore<double>::Matrix P0 = Eigen::Vector3d(0.1, 0.2, 0.3).asDiagonal();
  core.set(x0, P0);
  Eigen::Vector3d x = x0;
  Eigen::Matrix3d P = P0;
  UnscentedCore<double>::Matrix Qk = Q;
  UnscentedCore<double>::MMatrix Rk(1, 1);
  Rk(0, 0) = R;
  double worst = 0.0;
  for (int k = 0; k < 200; ++k) {
    const double u = std::sin(0.1 * k);
    const double y = std::cos(0.07 * k);
    if (!core.draw()) return INFINITY;
    Eigen::Matrix3d P_points = P;  // the covariance the update's points carry
    if (k > 0) {
      const bool ok = core.predict(
          [&](const double* s, double* next) {
            const Eigen::Vector3d moved = A * Eigen::Map<const Eigen::Vector3d>(s) + B * u;
            for (int i = 0; i < 3; ++i) next[i] = moved(i);
          },
          Qk);
      if (!ok) return INFINITY;
      x = A * x + B * u;
      P_points = A * P * A.transpose();
      P = P_points + Q;
      if (redraw) P_points = P;
    }
    UnscentedCore<double>::MVector ym(1);
    ym(0) = y;
    const bool ok = core.update(
        [&](const double* s, double* out) { out[0] = C.dot(Eigen::Map<const Eigen::Vector3d>(s)); }, ym, Rk);
    if (!ok) return INFINITY;
    const double Pyy = C.dot(P_points * C.transpose()) + R;
    const Eigen::Vector3d K = P_points * C.transpose() / Pyy;
    x = x + K * (y - C.dot(x));
    P = P - K * Pyy * K.transpose();
    worst = std::max(worst, (core.x() - x).cwiseAbs().maxCoeff());
    worst = std::max(worst, (core.P() - P).cwiseAbs().maxCoeff());
  }
  return worst;
}

TEST(UkfCore, LinearModelRedrawnIsTheKalmanFilter) {
  for (double alpha : {0.002, 0.5, 1.0}) {
    EXPECT_LT(linear_difference(alpha, true), 1e-8) << "alpha " << alpha;
  }
}

TEST(UkfCore, LinearModelPapersFormLeavesQOutOfTheUpdate) {
  for (double alpha : {0.002, 0.5, 1.0}) {
    EXPECT_LT(linear_difference(alpha, false), 1e-8) << "alpha " << alpha;
  }
}

TEST(UkfCore, RefusesACovarianceThatIsNotPositiveDefinite) {
  UnscentedCore<double> core;
  core.configure(2, 1, Weights::make(2, 0.5, 2.0, 0.0));
  UnscentedCore<double>::Vector x = Eigen::Vector2d(1.0, 2.0);
  UnscentedCore<double>::Matrix P(2, 2);
  P << 1.0, 2.0, 2.0, 1.0;  // indefinite
  core.set(x, P);
  EXPECT_FALSE(core.draw());
}

// --- the block, with plant.suspension and sensor.hall_gap ---------------------------------

const char* const kModels =
    "plant: {plugin: plant.suspension, mass_kg: 6.0e-3, force_b_n_m2_per_a: 4.85e-5}\n"
    "hall_distance: {plugin: sensor.hall_gap, output: gap}\n"
    "hall_volts: {plugin: sensor.hall_gap}\n"
    "hall_strong_coil: {plugin: sensor.hall_gap, coil_polynomial_v: [0.0, 0.1, 2.544]}\n";

const std::string kBlock = suspension_estimator(kHallDistanceNoise, 0.9);


void feed_standard(lode::testing::BlockHarness& h) {
  h.feed("measurement", {{"gap", "m"}});
  h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});  // like io.sim's truth
}

TEST(UkfBlock, PortsDescribeAndWeights) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  lode::testing::BlockHarness h("estimator.ukf", kBlock, 2000.0, kModels);
  feed_standard(h);
  ASSERT_TRUE(started(h));
  const lode::Elements& state = h.output_elements("state");
  ASSERT_EQ(state.size(), 3u);
  EXPECT_EQ(state[0].name, "gap");
  EXPECT_EQ(state[1].name, "velocity");
  EXPECT_EQ(state[2].unit, "A");
  EXPECT_EQ(h.output_elements("innovation")[0].name, "gap");
  EXPECT_NEAR(h.output("std")[0], 1e-3, 1e-15);  // sqrt(p0) before the first cycle
  const lode::Json d = h.describe();
  const lode::Json* filter = d.find("filter");
  ASSERT_NE(filter, nullptr) << d.dump();
  EXPECT_NEAR(filter->find("weight_mean_0")->as_number(), -249999.0, 1e-3);
  EXPECT_NEAR(filter->find("weight_cov_0")->as_number(), -249996.0, 1e-3);
  EXPECT_NEAR(filter->find("weight_i")->as_number(), 41666.6667, 1e-3);
  // per_second: Q_k = q dt.
  EXPECT_NEAR(d.find("Q_k")->elements()[2].elements()[2].as_number(), 7.71e-3 * kDt, 1e-18);
  const lode::Json* lin = d.find("linearised");
  ASSERT_NE(lin, nullptr);
  EXPECT_EQ(lin->find("F_source")->as_string(), "analytic (process model)");
  EXPECT_NE(lin->find("steady_state")->find("gain"), nullptr) << lin->dump();
  EXPECT_NE(d.find("process_model"), nullptr);
}

TEST(UkfBlock, TracksTheBenchmarkLikeTheCore) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark b = make_benchmark(3000);
  lode::testing::BlockHarness h(
      "estimator.ukf",
      suspension_estimator("measurement: hall_distance\nq: [2.8e-11, 8.5e-12, 3.855e-6]\nr: 1.2e-7\n", b.truth[0][2]),
      2000.0, kModels);
  feed_standard(h);
  ASSERT_TRUE(started(h));
  const CoreRun<double> core = run_core<double>(b, Sums::about_centre);
  ASSERT_TRUE(core.ok);
  double worst = 0.0;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    h.input("measurement")[0] = b.y[k];
    h.input("input")[0] = b.truth[k][0];
    h.input("input")[1] = b.u[k];
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << h.block().fault_reason();
    worst = std::max(worst, std::abs(h.output("state")[0] - core.x[k][0]));
  }
  EXPECT_LT(worst, 1e-10) << "the plugin's Euler step and the test's agree to rounding";
  EXPECT_LT(std::abs(h.output("state")[0] - b.truth.back()[0]), 50e-6);
  EXPECT_GT(h.output("std")[0], 0.0);
  EXPECT_LT(h.output("std")[0], 1e-4);
}

TEST(UkfBlock, EstimatesFromHallVoltagesThroughTheNonlinearModel) {
  // The measurement model may be the Hall sensor itself (h depends on the coil voltage, a
  // process input): the filter then runs on volts, R in V^2.
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark b = make_benchmark(3000);
  lode::testing::BlockHarness h(
      "estimator.ukf",
      suspension_estimator("measurement: hall_volts\nq: [5.6e-8, 1.7e-8, 7.71e-3]\nprocess_noise: per_second\nr: 4e-6\n",
                           b.truth[0][2]),
      2000.0, kModels);
  h.feed("measurement", {{"hall", "V"}});
  h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const lode::Json d = h.describe();
  EXPECT_EQ(d.find("measurement_depends_on")->elements()[1].as_string(), "coil_voltage (process input)");
  ASSERT_TRUE(h.activate());
  const lode::plugins::hall::Conversion c = lode::plugins::hall::Conversion::paper();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 2e-3);
  double sum = 0.0;
  int count = 0;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    const double hall_v = c.compensated_for_distance(b.truth[k][0] * 1e3) + c.coil_v.value(b.u[k]) + noise(rng);
    h.input("measurement")[0] = hall_v;
    h.input("input")[1] = b.u[k];
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << h.block().fault_reason();
    if (k >= 1000) {
      sum += std::pow(h.output("state")[0] - b.truth[k][0], 2);
      ++count;
    }
  }
  const double rms = std::sqrt(sum / count);
  std::printf("UKF on Hall volts (2 mV noise): gap error rms %.2f um\n", rms * 1e6);
  EXPECT_LT(rms, 40e-6);
}

TEST(UkfBlock, TheHallModelTakesTheCoilVoltageFromTheInput) {
  // h(gap, coil_voltage) with coil_voltage a process input, not a state: with 0.1 V per coil
  // volt (the paper's is 9e-5) reading anything else for it (e.g. the velocity, the state at
  // its position) would shift C_H by ~0.17 V, millimetres of gap.
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark b = make_benchmark(3000);
  lode::testing::BlockHarness h(
      "estimator.ukf",
      suspension_estimator(
          "measurement: hall_strong_coil\nq: [5.6e-8, 1.7e-8, 7.71e-3]\nprocess_noise: per_second\nr: 4e-6\n",
          b.truth[0][2]),
      2000.0, kModels);
  h.feed("measurement", {{"hall", "V"}});
  h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
  ASSERT_TRUE(started(h));
  lode::plugins::hall::Conversion c = lode::plugins::hall::Conversion::paper();
  c.coil_v = lode::plugins::hall::Polynomial::from({0.0, 0.1, 2.544});
  double worst = 0.0;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    h.input("measurement")[0] = c.compensated_for_distance(b.truth[k][0] * 1e3) + c.coil_v.value(b.u[k]);
    h.input("input")[1] = b.u[k];
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << h.block().fault_reason();
    if (k >= 1000) worst = std::max(worst, std::abs(h.output("state")[0] - b.truth[k][0]));
  }
  EXPECT_LT(worst, 100e-6) << "gap error of a noiseless Hall reading";
}

TEST(UkfBlock, NonFiniteInputFaultsAndLeavesTheEstimate) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  lode::testing::BlockHarness h("estimator.ukf", kBlock, 2000.0, kModels);
  feed_standard(h);
  ASSERT_TRUE(started(h));
  h.input("measurement")[0] = 0.026;
  h.input("input")[1] = 1.7;
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_TRUE(faults_and_holds(h, "measurement", 0, NAN, "non-finite measurement", "state"));
  h.input("measurement")[0] = 0.026;
  EXPECT_TRUE(faults_and_holds(h, "input", 1, INFINITY, "non-finite process input", "state"));
}

TEST(UkfBlock, ConfigurationErrorsAreReportedTogether) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  lode::testing::BlockHarness h("estimator.ukf",
                                "process: plant\nmeasurement: hall_distance\nq: [1, 2]\nr: -1\n"
                                "initial_state: [0.026]\np0: [1, 2, 2, 1, 0, 0, 0, 0, 1]\nalpha: 0\n"
                                "process_noise: hourly\n",
                                2000.0, kModels);
  h.feed("measurement", {{"distance", "mm"}, {"other", "V"}});
  h.feed("input", {{"coil_voltage", "A"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* what : {"q: expected 1, 3 (diagonal) or 9", "r: must be positive definite",
                           "initial_state: expected 3 numbers", "p0: must be symmetric", "process_noise",
                           "measurement: needs gap [m]", "input: element 'coil_voltage' is in A, expected V"}) {
    EXPECT_NE(d.find(what), std::string::npos) << what << "\n" << d;
  }
  lode::testing::BlockHarness h2("estimator.ukf", "process: nothing\nmeasurement: plant\nq: 1\nr: 1\n"
                                                  "initial_state: [0.026, 0, 0]\np0: 1\n",
                                 2000.0, kModels);
  feed_standard(h2);
  EXPECT_FALSE(h2.configure());
  EXPECT_NE(h2.diagnostics().find("no model named 'nothing'"), std::string::npos) << h2.diagnostics();
  EXPECT_NE(h2.diagnostics().find("this parameter needs a sensor model"), std::string::npos) << h2.diagnostics();
}

TEST(UkfBlock, AlphaOutOfRangeIsRefused) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  lode::testing::BlockHarness h("estimator.ukf", std::string(kBlock) + "alpha: 0\nkappa: -5\n", 2000.0, kModels);
  feed_standard(h);
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("alpha: the sigma-point spread alpha must be in (0, 1]"), std::string::npos)
      << h.diagnostics();
  EXPECT_NE(h.diagnostics().find("kappa: L + kappa must be > 0"), std::string::npos) << h.diagnostics();
}

TEST(UkfBlock, StepDoesNotAllocate) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  LODE_REQUIRE_ALLOCATION_COUNTING();
  for (const char* measurement : {"hall_distance", "hall_volts"}) {
    std::string block = kBlock;
    block.replace(block.find("hall_distance"), 13, measurement);
    if (std::string(measurement) == "hall_volts") block.replace(block.find("r: 1.2e-7"), 9, "r: 4e-6");
    lode::testing::BlockHarness h("estimator.ukf", block, 2000.0, kModels);
    h.feed("measurement", {{"gap", "m"}, {"hall", "V"}});
    h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
    ASSERT_TRUE(started(h));
    const Benchmark b = make_benchmark(10000);
    const lode::plugins::hall::Conversion c = lode::plugins::hall::Conversion::paper();
    auto measured = h.input("measurement");  // the spans, not a lookup per cycle
    auto input = h.input("input");
    const auto before = lode::testing::allocation_count();
    for (std::size_t k = 0; k < b.y.size(); ++k) {
      measured[0] = b.y[k];
      measured[1] = c.compensated_for_distance(b.y[k] * 1e3) + c.coil_v.value(b.u[k]);
      input[1] = b.u[k];
      ASSERT_EQ(h.step(), lode::StepStatus::ok) << h.block().fault_reason();
    }
    EXPECT_EQ(lode::testing::allocation_count() - before, 0u) << measurement;  // the model name
  }
}

constexpr const char* kStatePlugin = "estimator.ukf";
#include "estimator/testing/model_estimator_state_tests.inc"

TEST(UkfBlock, SizedAlgebraGivesTheGenericResultsBitForBit) {
  // The suspension (n = 3, m = 1) runs a core sized at compile time; compile_time_sizes: false
  // runs the generic one. Same operations in the same order: the same bits, cycle by cycle,
  // and neither allocates in step().
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const Benchmark b = make_benchmark(3000);
  lode::testing::BlockHarness sized("estimator.ukf", kBlock, 2000.0, kModels);
  lode::testing::BlockHarness generic("estimator.ukf", kBlock + "compile_time_sizes: false\n", 2000.0, kModels);
  for (auto* h : {&sized, &generic}) {
    feed_standard(*h);
    ASSERT_TRUE(started(*h));
  }
  EXPECT_TRUE(dynamic_cast<lode::plugins::UnscentedEstimator&>(sized.block()).fixed_size());
  EXPECT_FALSE(dynamic_cast<lode::plugins::UnscentedEstimator&>(generic.block()).fixed_size());
  EXPECT_EQ(generic.describe().find("filter")->find("algebra")->as_string(), "generic (sizes chosen at configure)");
  std::size_t allocations = 0;
  for (std::size_t k = 0; k < b.y.size(); ++k) {
    for (auto* h : {&sized, &generic}) {
      h->input("measurement")[0] = b.y[k];
      h->input("input")[0] = b.truth[k][0];
      h->input("input")[1] = b.u[k];
      allocations += lode::estimator_testing::allocations_during(
          [&] { ASSERT_EQ(h->step(), lode::StepStatus::ok) << h->block().fault_reason(); });
    }
    ASSERT_TRUE(lode::estimator_testing::same_outputs(sized, generic, {"state", "std", "innovation"}, k));
  }
  EXPECT_EQ(allocations, 0u) << "step() allocated";
}

}  // namespace
