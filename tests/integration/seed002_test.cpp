// Sensors 2016, 16, 1504 through the real loader and scheduler: force-fit constants
// (Table 3 -> Table 4), exact UKF weights, Hall conversion spot values, and the closed loop of
// config/suspension_ukf.yaml on a self-consistent plant: (i) the UKF-fed loop is stable for
// steps in 22-30 mm, (ii) the UKF's distance RMS error is at most 1/5 of the direct
// measurement's, (iii) the UKF is not an EKF: from the same state, one step of each differs
// sample by sample by the unscented transform's second-order mean term and by eq. 25's gains;
// Fig. 19's "UKF visibly better than the EKF" is a stated deviation (Seed002Deviation),
// (iv) the same loop fed by the direct measurement is unstable or clearly worse.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lode/sdk/estimator_state.hpp"
#include "config_text.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "tapped_run.hpp"

namespace {

using lode::test::emit;
using lode::test::read_file;

const std::string kConfig = LODE_SOURCE_DIR "/config/suspension_ukf.yaml";
constexpr double kDt = 0.5e-3;

const lode::Json& at(const lode::Json& j, const std::string& key) {
  const lode::Json* v = j.find(key);
  if (v == nullptr) throw std::runtime_error("describe() has no '" + key + "' in " + j.dump(-1).substr(0, 300));
  return *v;
}

lode::Json describe(const std::string& yaml) {
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(yaml, "seed002_test.yaml", registry, diag);
  EXPECT_TRUE(p) << diag.format();
  return p ? p->describe() : lode::Json();
}

/// One closed-loop run, sampled every cycle.
struct Trace {
  std::vector<double> t, truth, ukf, ekf, direct, ref, command;
  bool faulted = false;
  std::string fault;
  bool configured = false;

  /// RMS of (estimate - truth) over t in [t0, t1].
  [[nodiscard]] double rms(const std::vector<double>& estimate, double t0, double t1) const {
    double s = 0.0;
    int n = 0;
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (t[k] < t0 || t[k] > t1) continue;
      s += (estimate[k] - truth[k]) * (estimate[k] - truth[k]);
      ++n;
    }
    return n > 0 ? std::sqrt(s / n) : NAN;
  }
  [[nodiscard]] double min_gap() const { return truth.empty() ? NAN : *std::min_element(truth.begin(), truth.end()); }
  [[nodiscard]] double max_gap() const { return truth.empty() ? NAN : *std::max_element(truth.begin(), truth.end()); }
  /// The magnet stayed clear of the end stops (12 mm coil face, 50 mm floor) and of the snap
  /// region: between 18 and 34 mm all the time.
  [[nodiscard]] bool held() const { return !faulted && !truth.empty() && min_gap() > 0.018 && max_gap() < 0.034; }
};

Trace run(const std::string& yaml, double seconds) {
  Trace tr;
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(yaml, "seed002_test.yaml", registry, diag);
  EXPECT_TRUE(p) << diag.format();
  if (!p) return tr;
  tr.configured = true;
  EXPECT_TRUE(p->activate());
  const lode::test::TappedRun run =
      lode::test::run_tapped(*p, {"stage.plant_state", "ukf.state", "ekf.state", "direct.gap", "ref.out", "ctrl.out"},
                             static_cast<std::uint64_t>(std::llround(seconds * p->rate_hz())), 1 << 14);
  tr.faulted = run.faulted;
  tr.fault = run.fault;
  for (std::size_t k = 0; k < run.size(); ++k) {
    tr.t.push_back(run.time_s(k));
    tr.truth.push_back(*run.values(k, 0));
    tr.ukf.push_back(*run.values(k, 1));
    tr.ekf.push_back(*run.values(k, 2));
    tr.direct.push_back(*run.values(k, 3));
    tr.ref.push_back(*run.values(k, 4));
    tr.command.push_back(*run.values(k, 5));
  }
  p->deactivate();
  return tr;
}

YAML::Node config() { return YAML::Load(read_file(kConfig)); }

/// Reference steps (gap only; velocity 0 and the hold current ride along for the monitor).
void set_steps(YAML::Node& root, double start, const std::vector<std::pair<double, double>>& steps) {
  YAML::Node ref = root["blocks"]["ref"];
  ref["offset"] = std::vector<double>{start, 0.0, 0.0};
  YAML::Node list(YAML::NodeType::Sequence);
  for (const auto& [time_s, gap] : steps) {
    YAML::Node s;
    s["time_s"] = time_s;
    s["value"] = std::vector<double>{gap, 0.0, 0.0};
    list.push_back(s);
  }
  ref["steps"] = list;
}

// --- the figures that are reproducible exactly (Table 4, eq. 21, eq. 16) -----------------

TEST(Seed002Paper, ForceFitConstantsOfTable4) {
  // Table 3's per-current fits through the plant's stage-2 fit (eq. 11-12).
  YAML::Node root = config();
  YAML::Node plant = root["models"]["levitator"];
  plant.remove("force_a_n_m4");
  plant.remove("force_b_n_m2_per_a");
  plant["force_fit"]["current_a"] = std::vector<double>{0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4};
  plant["force_fit"]["a_n_m4"] =
      std::vector<double>{5.999e-9, 5.98e-9, 6.012e-9, 6.005e-9, 5.985e-9, 5.994e-9, 5.989e-9, 6.007e-9};
  plant["force_fit"]["b_n_m2"] =
      std::vector<double>{7.587e-8, 88.6e-8, 174.4e-8, 263.4e-8, 357.1e-8, 450.6e-8, 543.1e-8, 637.2e-8};
  const lode::Json d = describe(emit(root));
  const lode::Json& fit = at(at(at(at(at(d, "blocks"), "stage"), "derived"), "plant_model"), "force_fit");
  const double a = at(fit, "a_mean").as_number();
  const double m = at(fit, "b_per_current").as_number();
  const double j3 = at(fit, "j3").as_number();
  std::printf("Table 4: a = %.5e (printed 5.996e-9, %+.3f %%), m = %.5e (4.509e-6, %+.3f %%), "
              "J_3 = %.4e (2.0486e-14, %+.1f %%)\n",
              a, 100 * (a / 5.996e-9 - 1), m, 100 * (m / 4.509e-6 - 1), j3, 100 * (j3 / 2.0486e-14 - 1));
  EXPECT_NEAR(a / 5.996e-9, 1.0, 1e-3);   // +-0.1 %
  EXPECT_NEAR(m / 4.509e-6, 1.0, 5e-3);   // +-0.5 %
  EXPECT_NEAR(j3 / 2.0486e-14, 1.0, 0.1); // +-10 %
}

TEST(Seed002Paper, UkfWeightsAreExact) {
  const lode::Json d = describe(read_file(kConfig));
  const lode::Json& filter = at(at(at(at(d, "blocks"), "ukf"), "derived"), "filter");
  const double w0m = at(filter, "weight_mean_0").as_number();
  const double w0c = at(filter, "weight_cov_0").as_number();
  const double wi = at(filter, "weight_i").as_number();
  std::printf("weights: W0m %.6f, W0c %.6f, Wi %.6f (printed -2.499e5, -2.5e5, 0.416e5)\n", w0m, w0c, wi);
  // Json keeps 10 significant digits: relative 1e-9 is what it can carry.
  EXPECT_NEAR(w0m / -249999.0, 1.0, 1e-9);
  EXPECT_NEAR(w0c / -249996.0, 1.0, 1e-9);
  EXPECT_NEAR(wi / (250000.0 / 6.0), 1.0, 1e-9);
  EXPECT_NEAR(w0m + 6 * wi, 1.0, 1e-4);  // the sum of the mean weights, from 10-digit numbers
  EXPECT_NEAR(at(filter, "sum_mean_weights").as_number(), 1.0, 1e-9);
}

TEST(Seed002Paper, HallConversionSpotValues) {
  const lode::Json d = describe(read_file(kConfig));
  const lode::Json& table = at(at(at(at(d, "blocks"), "direct"), "derived"), "sensitivity");
  const double printed_mm[] = {46.9, 33.69, 27.15, 23.61, 21.27, 19.55, 18.41, 17.65, 16.29};
  ASSERT_EQ(table.elements().size(), 9u);
  double previous = INFINITY;
  for (std::size_t k = 0; k < 9; ++k) {
    const double gap_mm = 1e3 * at(table.elements()[k], "gap_m").as_number();
    EXPECT_NEAR(gap_mm, printed_mm[k], 0.01) << "C_H = " << 0.1 * static_cast<double>(k);
    EXPECT_LT(at(table.elements()[k], "slope_m_per_v").as_number(), 0.0);
    EXPECT_LT(gap_mm, previous);
    previous = gap_mm;
  }
  EXPECT_DOUBLE_EQ(1e3 * at(table.elements()[0], "gap_m").as_number(), 46.9);
}

// --- the closed loop (qualitative, on a self-consistent plant) ----------------------------

TEST(Seed002ClosedLoop, UkfFedLoopHoldsAndFollowsStepsAcross22To30mm) {
  // (i) The shipped pipeline: 26 -> 22 -> 30 -> 24 -> 28 -> 25 mm, one second each.
  const Trace tr = run(read_file(kConfig), 6.0);
  ASSERT_FALSE(tr.faulted) << tr.fault;
  ASSERT_EQ(tr.t.size(), 12000u);
  std::printf("gap range %.2f ... %.2f mm\n", tr.min_gap() * 1e3, tr.max_gap() * 1e3);
  EXPECT_TRUE(tr.held());
  for (int segment = 0; segment < 6; ++segment) {
    // The last 0.3 s of each segment: settled on the reference.
    double sum = 0.0;
    int n = 0;
    for (std::size_t k = 0; k < tr.t.size(); ++k) {
      if (tr.t[k] < segment + 0.7 || tr.t[k] >= segment + 1.0) continue;
      sum += tr.truth[k] - tr.ref[k];
      ++n;
    }
    const double mean_error = sum / n;
    std::printf("segment %d (ref %.0f mm): mean gap error %+.1f um\n", segment, tr.ref[static_cast<std::size_t>(segment * 2000 + 1999)] * 1e3,
                mean_error * 1e6);
    EXPECT_LT(std::abs(mean_error), 50e-6) << "segment " << segment;
  }
  for (double u : tr.command) {
    ASSERT_GE(u, 0.5);
    ASSERT_LE(u, 3.0);
  }
}

/// sqrt(2 lambda t_s): the error/measurement-noise ratio of the best causal estimate of an
/// unstable mode with pole lambda observed in white noise (the Q -> 0 Kalman filter),
/// at the mean unstable pole of 22-30 mm (plant.suspension describe(): 36 ... 27 rad/s).
double estimation_floor(double lambda_rad_s) { return std::sqrt(2.0 * lambda_rad_s * kDt); }

TEST(Seed002ClosedLoop, UkfErrorIsAtMostAFifthOfTheDirectMeasurement) {
  // (ii) RMS(UKF - truth) <= RMS(direct - truth) / 5 over the run (after 0.2 s). Printed
  // (Table 6, PID): direct 15.71e-5, UKF 1.68e-5 (1/9.4); backstepping 12.32e-5 / 1.52e-5.
  const Trace tr = run(read_file(kConfig), 6.0);
  ASSERT_FALSE(tr.faulted) << tr.fault;
  const double direct = tr.rms(tr.direct, 0.2, 6.0);
  const double ukf = tr.rms(tr.ukf, 0.2, 6.0);
  const double ekf = tr.rms(tr.ekf, 0.2, 6.0);
  std::printf("RMS error: direct %.2e m (Table 6 PID 15.71e-5), UKF %.2e m (1.68e-5), EKF %.2e m; "
              "UKF/direct = 1/%.2f (paper 1/9.4), floor sqrt(2 lambda t_s) = 1/%.1f..1/%.1f\n",
              direct, ukf, ekf, direct / ukf, 1.0 / estimation_floor(36.0), 1.0 / estimation_floor(27.0));
  EXPECT_GT(direct, 1.0e-4);  // the noise model puts the direct measurement near Table 6
  EXPECT_LT(direct, 2.0e-4);
  EXPECT_LE(ukf, direct / 5.0);
}

TEST(Seed002ClosedLoop, FifthOfTheDirectMeasurementOverFiveNoiseSeeds) {
  // The ratio sits just under the floor of any causal estimator here (sqrt(2 lambda t_s),
  // 1/5.3 ... 1/6.1 over 22-30 mm), and one 6 s run scatters by +-10 % around it because the
  // UKF's error is correlated over ~1/lambda = 30 ms. So the criterion is checked on five noise
  // realisations pooled (30 s); each single run is printed and pinned at <= 0.21 (seed 1
  // gives 0.203: a single run may miss 1/5 by a few per cent -- see README).
  double ukf_sq = 0.0, direct_sq = 0.0;
  for (int seed = 1; seed <= 5; ++seed) {
    YAML::Node root = config();
    root["blocks"]["stage"]["seed"] = seed;
    const Trace tr = run(emit(root), 6.0);
    ASSERT_FALSE(tr.faulted) << tr.fault;
    ASSERT_TRUE(tr.held()) << "seed " << seed;
    const double ukf = tr.rms(tr.ukf, 0.2, 6.0);
    const double direct = tr.rms(tr.direct, 0.2, 6.0);
    ukf_sq += ukf * ukf;
    direct_sq += direct * direct;
    std::printf("seed %d: UKF/direct RMS = %.3f (1/%.2f), EKF/direct = %.3f\n", seed, ukf / direct, direct / ukf,
                tr.rms(tr.ekf, 0.2, 6.0) / direct);
    EXPECT_LE(ukf / direct, 0.21) << "seed " << seed << " (pinned; the criterion is the pooled ratio)";
  }
  const double pooled = std::sqrt(ukf_sq / direct_sq);
  std::printf("pooled over five seeds: UKF/direct RMS = %.3f (1/%.2f); criterion <= 1/5, paper 1/8 ... 1/9.4\n",
              pooled, 1.0 / pooled);
  EXPECT_LE(pooled, 0.2);
}

// --- UKF against EKF (Fig. 19) ------------------------------------------------------------

/// Fig. 19's scenario: the reference switches between 22 and 25 mm every 0.5 s from rest at
/// 22 mm; the loop is fed by the UKF and the EKF runs beside it on the same samples.
YAML::Node fig19_config(int seed) {
  YAML::Node root = config();
  set_steps(root, 0.022, {{0.5, 0.025}, {1.0, 0.022}, {1.5, 0.025}, {2.0, 0.022}, {2.5, 0.025}, {3.0, 0.022},
                          {3.5, 0.025}, {4.0, 0.022}, {4.5, 0.025}, {5.0, 0.022}, {5.5, 0.025}});
  root["models"]["levitator"]["initial_gap_m"] = 0.022;
  root["blocks"]["ukf"]["initial_state"] = std::vector<double>{0.022, 0.0, 0.332};
  root["blocks"]["ekf"]["initial_state"] = std::vector<double>{0.022, 0.0, 0.332};
  root["blocks"]["ctrl"]["initial_output"] = 0.8923;
  root["blocks"]["stage"]["seed"] = seed;
  return root;
}

/// The filters' process model, eq. 33 (Euler), written out from the pipeline's constants:
/// x = (gap d, velocity v, current i), acceleration(d, i) = g - (a d^-4 + b i d^-2) / m. Only
/// the velocity row is nonlinear; the gap row d + t_s v and the current row are linear.
struct EulerSuspension {
  double a = 0.0, b = 0.0, mass = 0.0, gravity = 0.0, coil_decay = 0.0, dt = 0.0;

  explicit EulerSuspension(const YAML::Node& root) {
    const YAML::Node m = root["models"]["levitator"];
    a = m["force_a_n_m4"].as<double>();
    b = m["force_b_n_m2_per_a"].as<double>();
    mass = m["mass_kg"].as<double>();
    gravity = m["gravity_m_s2"].as<double>();
    coil_decay = m["coil_decay_1_per_s"].as<double>();
    dt = 1.0 / root["rate_hz"].as<double>();
  }
  /// d(acceleration)/d(gap) and d(acceleration)/d(current).
  [[nodiscard]] double slope_gap(const Eigen::Vector3d& x) const {
    return (4.0 * a * std::pow(x(0), -5) + 2.0 * b * x(2) * std::pow(x(0), -3)) / mass;
  }
  [[nodiscard]] double slope_current(const Eigen::Vector3d& x) const { return -b * std::pow(x(0), -2) / mass; }
  /// The second derivatives; d^2/di^2 is 0.
  [[nodiscard]] double curvature_gap(const Eigen::Vector3d& x) const {
    return -(20.0 * a * std::pow(x(0), -6) + 6.0 * b * x(2) * std::pow(x(0), -4)) / mass;
  }
  [[nodiscard]] double curvature_gap_current(const Eigen::Vector3d& x) const {
    return 2.0 * b * std::pow(x(0), -3) / mass;
  }
  /// F = I + t_s df/dx, the EKF's Jacobian.
  [[nodiscard]] Eigen::Matrix3d jacobian(const Eigen::Vector3d& x) const {
    Eigen::Matrix3d F;
    F << 1.0, dt, 0.0,                                      //
        dt * slope_gap(x), 1.0, dt * slope_current(x),      //
        0.0, 0.0, 1.0 - dt * coil_decay;
    return F;
  }
  /// 1/2 tr(Hess(acceleration) P): the second-order term of the mean acceleration over a
  /// spread P of states, which a mean propagated through f alone (the EKF) leaves out.
  [[nodiscard]] double mean_acceleration_shift(const Eigen::Vector3d& x, const Eigen::Matrix3d& P) const {
    return 0.5 * curvature_gap(x) * P(0, 0) + curvature_gap_current(x) * P(0, 2);
  }
  /// sqrt(g' P g), g the acceleration's gradient: its first-order spread over P.
  [[nodiscard]] double acceleration_spread(const Eigen::Vector3d& x, const Eigen::Matrix3d& P) const {
    const Eigen::Vector3d g(slope_gap(x), 0.0, slope_current(x));
    return std::sqrt(g.dot(P * g));
  }
};

/// One cycle k of the UKF and the EKF, with the UKF's state before it.
struct FilterCycle {
  double t = 0.0;
  Eigen::Vector3d ukf_before = Eigen::Vector3d::Zero();  ///< x_{k-1|k-1}
  Eigen::Matrix3d ukf_covariance_before = Eigen::Matrix3d::Zero();  ///< P_{k-1|k-1}
  Eigen::Vector3d ukf = Eigen::Vector3d::Zero();  ///< x_{k|k}
  Eigen::Vector3d ekf = Eigen::Vector3d::Zero();
  double ukf_innovation = 0.0;  ///< y_k - y^_{k|k-1}
  double ekf_innovation = 0.0;
  double truth_gap = 0.0;
};

/// The pipeline run cycle by cycle, exactly as the scheduler runs it on the simulated clock,
/// reading the UKF's exported state (x_{k-1|k-1}, P_{k-1|k-1}) before every cycle from the
/// second on. With `ekf_restarts_from_ukf` that state is imported into the EKF first, so that
/// in every cycle both filters start from the same (x, P) and take the same sample y_k and
/// input u_{k-1}: the difference of their outputs is one step of each algorithm, nothing else.
std::vector<FilterCycle> run_cycles(const std::string& yaml, double seconds, bool ekf_restarts_from_ukf) {
  std::vector<FilterCycle> out;
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(yaml, "seed002_test.yaml", registry, diag);
  EXPECT_TRUE(p) << diag.format();
  if (!p) return out;
  EXPECT_TRUE(p->activate());
  auto* ukf = dynamic_cast<lode::EstimatorState*>(p->block("ukf"));
  auto* ekf = dynamic_cast<lode::EstimatorState*>(p->block("ekf"));
  if (!ukf || !ekf) {
    ADD_FAILURE() << "the UKF and the EKF export their state";
    return out;
  }
  const lode::StateLayout layout = ukf->state_layout();
  EXPECT_EQ(layout.size(), 3u);
  EXPECT_TRUE(layout.covariance);
  const double* ukf_state = p->signal("ukf.state")->data;
  const double* ekf_state = p->signal("ekf.state")->data;
  const double* ukf_innovation = p->signal("ukf.innovation")->data;
  const double* ekf_innovation = p->signal("ekf.innovation")->data;
  const double* truth = p->signal("stage.plant_state")->data;
  const auto cycles = static_cast<std::uint64_t>(std::llround(seconds * p->rate_hz()));
  lode::Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  std::array<double, 3> x{};
  std::array<double, 9> P{};
  const std::array<std::uint8_t, 3> present = {1, 1, 1};
  for (std::uint64_t k = 0; k < cycles; ++k) {
    ukf->export_state(x.data(), P.data());
    if (ekf_restarts_from_ukf && k > 0) ekf->import_state(x.data(), P.data(), present.data());
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    const auto result = p->run_cycle(tick, false);
    if (result.status != lode::StepStatus::ok) {
      ADD_FAILURE() << "fault in cycle " << k;
      break;
    }
    if (k == 0) continue;  // the first cycle only updates the initial state
    FilterCycle c;
    c.t = static_cast<double>(tick.time_ns) * 1e-9;
    c.ukf_before = Eigen::Vector3d(x[0], x[1], x[2]);
    c.ukf_covariance_before = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(P.data());
    c.ukf = Eigen::Vector3d(ukf_state[0], ukf_state[1], ukf_state[2]);
    c.ekf = Eigen::Vector3d(ekf_state[0], ekf_state[1], ekf_state[2]);
    c.ukf_innovation = ukf_innovation[0];
    c.ekf_innovation = ekf_innovation[0];
    c.truth_gap = truth[0];
    out.push_back(c);
  }
  p->deactivate();
  return out;
}

TEST(Seed002ClosedLoop, UkfAddsTheSecondOrderMeanTermTheEkfLacks) {
  // (iii) The UKF of eq. 20-31 is not the EKF. From the same (x, P), sample y_k and input, one
  // step of each differs by
  //     x_ukf - x_ekf = c + (K_ukf - K_ekf) nu,
  // nu = y_k - (d + t_s v) being the same for both (h and the gap row of f are linear), where
  //  * c = (0, t_s 1/2 tr(Hess(acceleration) P), 0). The weighted mean of f over the sigma
  //    points is f(x) + 1/2 tr(Hess f P) up to fourth-order terms of relative size
  //    alpha^2 (L + kappa) P = 1.2e-5 P; the EKF propagates the mean through f alone.
  //  * K_ukf = F P F' H' / (H F P F' H' + R): eq. 25 sends the propagated points through h
  //    without redrawing them, so Q_k reaches neither P_yy nor P_xy; K_ekf = P^- H' (H P^- H' +
  //    R)^-1 with P^- = F P F' + Q_k. (The points' covariance is F P F' up to terms of the same
  //    alpha^2 order; the term c c' it also carries does not reach the gain, c having no gap.)
  // Checked sample by sample, each part on its own row: the gap row carries the gain part
  // alone; the velocity row, once the gain part is taken off, must be c. An EKF in the ukf role
  // makes the difference 0; a broken unscented transform (spread, weights, sums) changes c or
  // the gains.
  // The sign of c is the force law's: a d^-4 + b i d^-2 is convex in the gap, so a spread of
  // gaps pulls harder on average than the mean gap (Jensen) and the UKF predicts a lower
  // velocity than the EKF. The gap-current term of the trace (2 b / (m d^3) P_di) could reverse
  // that; it is asserted to stay below half the gap term.
  const YAML::Node root = fig19_config(1);
  const EulerSuspension model(root);
  const std::vector<double> q = root["blocks"]["ukf"]["q"].as<std::vector<double>>();
  const Eigen::Matrix3d Q = model.dt * Eigen::Vector3d(q[0], q[1], q[2]).asDiagonal().toDenseMatrix();
  const double R = root["blocks"]["ukf"]["r"].as<double>();
  // Rounding: the unscented sums weigh each propagated point's rounding (an ulp or so of |x|) by
  // W_i = 1 / (2 alpha^2 (L + kappa)) = 41667, over 2L = 6 points: 6 W_i eps relative to |x|.
  const double alpha = root["blocks"]["ukf"]["alpha"].as<double>(0.002);  // eq. 21's value if absent
  const double rounding = 6.0 / (2.0 * alpha * alpha * 3.0) * std::numeric_limits<double>::epsilon();
  // c is compared to 1e-3 of itself: over 100 times that rounding floor (6 W_i eps |v| with |v|
  // below 0.05 m/s is 3e-12 m/s, against |c| above 1e-7 m/s here) and over 1000 times the
  // transform's own fourth-order remainder.
  constexpr double kMeanTermTolerance = 1e-3;
  const std::vector<FilterCycle> cycles = run_cycles(emit(root), 3.0, true);
  ASSERT_EQ(cycles.size(), 5999u);
  double worst_gap_error = 0.0, worst_velocity_error = 0.0, worst_cross_share = 0.0;
  double sum_c = 0.0, sum_gain_part = 0.0, sum_update = 0.0, sum_gap_gain_part = 0.0;
  int positive_c = 0, n = 0;
  for (const FilterCycle& cy : cycles) {
    const Eigen::Vector3d& x = cy.ukf_before;
    const Eigen::Matrix3d& P = cy.ukf_covariance_before;
    const Eigen::Matrix3d F = model.jacobian(x);
    const Eigen::Matrix3d points = F * P * F.transpose();
    const Eigen::Matrix3d prior = points + Q;
    const Eigen::Vector3d gain_ukf = points.col(0) / (points(0, 0) + R);
    const Eigen::Vector3d gain_ekf = prior.col(0) / (prior(0, 0) + R);
    const double nu = cy.ukf_innovation;
    const Eigen::Vector3d gain_part = (gain_ukf - gain_ekf) * nu;
    const double c = model.dt * model.mean_acceleration_shift(x, P);
    const Eigen::Vector3d difference = cy.ukf - cy.ekf;
    ASSERT_NEAR(cy.ekf_innovation, nu, rounding * std::abs(x(0))) << "t = " << cy.t;
    if (cy.t < 0.1) continue;  // P from p0 settles within ~0.05 s
    const double gap_error = std::abs(difference(0) - gain_part(0));
    const double velocity_error = std::abs(difference(1) - gain_part(1) - c) / std::abs(c);
    const double cross_share =
        std::abs(model.curvature_gap_current(x) * P(0, 2)) / std::abs(0.5 * model.curvature_gap(x) * P(0, 0));
    EXPECT_LE(gap_error, rounding * std::abs(x(0))) << "t = " << cy.t << ": gap row is not the gains' difference";
    EXPECT_LE(velocity_error, kMeanTermTolerance) << "t = " << cy.t << ": velocity row is not c + the gains' part";
    EXPECT_LT(cross_share, 0.5) << "t = " << cy.t;
    EXPECT_LT(c, 0.0) << "t = " << cy.t;
    if (HasFailure()) return;  // one sample tells; do not print 6000
    worst_gap_error = std::max(worst_gap_error, gap_error);
    worst_velocity_error = std::max(worst_velocity_error, velocity_error);
    worst_cross_share = std::max(worst_cross_share, cross_share);
    sum_c += c * c;
    sum_gain_part += gain_part(1) * gain_part(1);
    sum_gap_gain_part += gain_part(0) * gain_part(0);
    sum_update += (gain_ukf(1) * nu) * (gain_ukf(1) * nu);
    if (c >= 0.0) ++positive_c;
    ++n;
  }
  std::printf("one step of each filter from the same (x, P), %d cycles of Fig. 19's steps:\n"
              "  gap:      rms (K_ukf - K_ekf) nu = %.3e m, worst |measured - that| = %.2e m (floor %.2e m)\n"
              "  velocity: rms c = %.3e m/s (%d of %d positive), rms (K_ukf - K_ekf) nu = %.3e m/s, "
              "rms K_ukf nu = %.3e m/s;\n            worst |measured - gains' part - c| / |c| = %.2e; "
              "gap-current / gap term of c <= %.3f\n",
              n, std::sqrt(sum_gap_gain_part / n), worst_gap_error, rounding * 0.022, std::sqrt(sum_c / n),
              positive_c, n, std::sqrt(sum_gain_part / n), std::sqrt(sum_update / n), worst_velocity_error,
              worst_cross_share);
}

TEST(Seed002Deviation, UkfIsNotVisiblyBetterThanTheEkf) {
  // Paper (Fig. 19, references in 22-25 mm): the UKF tracks and smooths visibly better than the
  // EKF; no numbers. Here, with the same model, Q, R and samples in both and the loop fed by
  // the UKF, the UKF/EKF RMS gap error is within 1 % of 1 on each of five noise seeds (pooled:
  // not worse). Why: all the unscented transform adds to the EKF's linearisation is the
  // second-order term c of the test above (the gain difference of eq. 25 is the paper's form,
  // not the transform). Over the filter's own uncertainty P that term is below 1 % of the
  // first-order spread of the predicted acceleration: the gap's posterior std is at most
  // 0.32 % of the gap, and the force law's second derivative is (20 a d^-6 + 6 b i d^-4) /
  // (4 a d^-5 + 2 b i d^-3) = 4.2 / d times its first at 22 mm, so over one std the
  // second-order term is about 2 sigma/d = 0.6 % of the first-order one (0.5 % once the
  // current's share of the spread is counted). A term that small cannot make the errors
  // differ by more than about as much, so the UKF cannot be visibly better here (with the
  // mean taken from the centre point alone, UKF/EKF is 1.00000: c is the whole difference).
  // Fig. 19's difference needs a filter whose uncertainty spans a visibly curved part of the
  // force law (a much larger P), or an EKF tuned differently from the UKF (the paper does not
  // say it used the same Q and R).
  const double kStart = 0.2;
  double ukf_total = 0.0, ekf_total = 0.0;
  for (int seed = 1; seed <= 5; ++seed) {
    const YAML::Node root = fig19_config(seed);
    const EulerSuspension model(root);
    const std::vector<FilterCycle> cycles = run_cycles(emit(root), 6.0, false);
    ASSERT_EQ(cycles.size(), 11999u);
    double ukf_sq = 0.0, ekf_sq = 0.0, worst_curvature = 0.0, worst_relative_std = 0.0;
    int n = 0;
    bool held = true;
    for (const FilterCycle& cy : cycles) {
      held = held && cy.truth_gap > 0.018 && cy.truth_gap < 0.034;
      if (cy.t < kStart) continue;
      ukf_sq += (cy.ukf(0) - cy.truth_gap) * (cy.ukf(0) - cy.truth_gap);
      ekf_sq += (cy.ekf(0) - cy.truth_gap) * (cy.ekf(0) - cy.truth_gap);
      const double shift = model.mean_acceleration_shift(cy.ukf_before, cy.ukf_covariance_before);
      const double spread = model.acceleration_spread(cy.ukf_before, cy.ukf_covariance_before);
      worst_curvature = std::max(worst_curvature, std::abs(shift) / spread);
      worst_relative_std =
          std::max(worst_relative_std, std::sqrt(cy.ukf_covariance_before(0, 0)) / cy.ukf_before(0));
      ++n;
    }
    ASSERT_TRUE(held) << "seed " << seed;
    const double ukf = std::sqrt(ukf_sq / n), ekf = std::sqrt(ekf_sq / n);
    ukf_total += ukf_sq;
    ekf_total += ekf_sq;
    std::printf("seed %d, 22-25 mm steps: UKF %.3f um, EKF %.3f um, UKF/EKF = %.5f; second-order / first-order "
                "acceleration over P: worst %.2e (gap std / gap <= %.2e)\n",
                seed, ukf * 1e6, ekf * 1e6, ukf / ekf, worst_curvature, worst_relative_std);
    EXPECT_LT(worst_curvature, 0.01) << "seed " << seed;
    EXPECT_NEAR(ukf / ekf, 1.0, 0.01) << "seed " << seed;
  }
  const double ratio = std::sqrt(ukf_total / ekf_total);
  std::printf("UKF/EKF RMS over five seeds: %.5f (paper, Fig. 19: the UKF visibly better, no numbers)\n", ratio);
  EXPECT_LE(ratio, 1.0) << "the UKF should not be worse than the EKF";
}

TEST(Seed002ClosedLoop, DirectFeedbackIsUnstableOrClearlyWorse) {
  // (iv) The PID fed by d_hall instead of the UKF's gap: the derivative of 0.1 mm of noise.
  YAML::Node root = config();
  const Trace ukf_fed = run(emit(root), 6.0);
  ASSERT_TRUE(ukf_fed.held());
  const double ukf_tracking = ukf_fed.rms(ukf_fed.ref, 0.2, 6.0);
  root["blocks"]["ctrl"]["inputs"]["measurement"] = "direct.gap";
  root["blocks"]["ctrl"].remove("axes");
  root["blocks"]["ctrl"]["axes"] = std::vector<std::string>{"gap"};
  int lost = 0;
  for (int seed = 1; seed <= 5; ++seed) {
    root["blocks"]["stage"]["seed"] = seed;
    const Trace tr = run(emit(root), 6.0);
    ASSERT_TRUE(tr.configured);
    const bool held = tr.held();
    const double tracking = tr.rms(tr.ref, 0.2, 6.0);
    std::printf("seed %d, fed by d_hall: %s, gap %.1f ... %.1f mm, tracking RMS %.3f mm (UKF-fed %.3f mm)\n", seed,
                held ? "held" : "LOST", tr.min_gap() * 1e3, tr.max_gap() * 1e3, tracking * 1e3, ukf_tracking * 1e3);
    if (!held) ++lost;
    EXPECT_TRUE(!held || tracking > 5.0 * ukf_tracking) << "seed " << seed;
  }
  std::printf("direct feedback lost the magnet in %d of 5 runs (the paper: unstable)\n", lost);
}

TEST(Seed002ClosedLoop, EkfFedLoopIsStableToo) {
  YAML::Node root = config();
  root["blocks"]["ctrl"]["inputs"]["measurement"] = "ekf.state";
  const Trace tr = run(emit(root), 6.0);
  ASSERT_FALSE(tr.faulted) << tr.fault;
  EXPECT_TRUE(tr.held());
  EXPECT_LT(tr.rms(tr.ekf, 0.2, 6.0), tr.rms(tr.direct, 0.2, 6.0) / 5.0);
}

TEST(Seed002ClosedLoop, PrintedEq35CoefficientsDoNotHoldThisPlant) {
  // Eq. 35 as printed was tuned on the massless linearisation of eq. 32 (so says the paper): on the
  // self-consistent plant its derivative action (-0.49 V*s/m against the ~17 needed) cannot
  // stabilise the magnet. Pinned so that a change in the plant or the PID shows here.
  YAML::Node root = config();
  YAML::Node ctrl = root["blocks"]["ctrl"];
  for (const char* key : {"kp", "ki", "kd", "derivative_filter_rad_s", "setpoint_weight_p", "setpoint_weight_d"})
    ctrl.remove(key);
  ctrl["coefficients"]["numerator"] = std::vector<double>{-623.9, 1020, -386.8};
  ctrl["coefficients"]["denominator"] = std::vector<double>{1, -1.604, 0.603};
  const Trace tr = run(emit(root), 3.0);
  ASSERT_TRUE(tr.configured);
  std::printf("eq. 35 as printed: gap %.1f ... %.1f mm\n", tr.min_gap() * 1e3, tr.max_gap() * 1e3);
  EXPECT_FALSE(tr.held());
}

}  // namespace
