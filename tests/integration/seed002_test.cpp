// Seed 002 (Sensors 2016, 16, 1504) through the real loader and scheduler: the pass criteria of
// spec seed-002-hall-ukf.md §5.3 -- force-fit constants (Table 3 -> Table 4), exact UKF
// weights, Hall conversion spot values, and the closed loop of config/suspension_ukf.yaml on a
// self-consistent plant: (i) the UKF-fed loop is stable for steps in 22-30 mm, (ii) the UKF's
// distance RMS error is at most 1/5 of the direct measurement's, (iii) UKF vs EKF on 22-25 mm
// steps, (iv) the same loop fed by the direct measurement is unstable or clearly worse.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"

namespace {

const std::string kConfig = LODE_SOURCE_DIR "/config/suspension_ukf.yaml";
constexpr double kDt = 0.5e-3;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string emit(const YAML::Node& root) {
  YAML::Emitter out;
  out << root;
  return out.c_str();
}

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
  const auto truth = *p->signal("stage.plant_state");
  const auto ukf = *p->signal("ukf.state");
  const auto ekf = *p->signal("ekf.state");
  const auto direct = *p->signal("direct.gap");
  const auto ref = *p->signal("ref.out");
  const auto command = *p->signal("ctrl.out");
  lode::SignalTap tap({truth, ukf, ekf, direct, ref, command}, 1 << 14);
  lode::SimulatedClock clock;
  lode::EventLog events;
  lode::Scheduler sched(*p, clock, events);
  sched.add_tap(&tap);
  std::vector<double> rows;
  std::atomic<bool> stop{false};
  const auto result =
      sched.run(static_cast<std::uint64_t>(std::llround(seconds * p->rate_hz())), stop, [&] { tap.drain(rows); });
  tap.drain(rows);
  tr.faulted = result.faulted;
  tr.fault = result.fault;
  const std::size_t stride = tap.stride();
  for (std::size_t k = 0; k + stride <= rows.size(); k += stride) {
    tr.t.push_back(rows[k + 1]);
    tr.truth.push_back(rows[k + tap.column(0)]);
    tr.ukf.push_back(rows[k + tap.column(1)]);
    tr.ekf.push_back(rows[k + tap.column(2)]);
    tr.direct.push_back(rows[k + tap.column(3)]);
    tr.ref.push_back(rows[k + tap.column(4)]);
    tr.command.push_back(rows[k + tap.column(5)]);
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

// --- the figures that are reproducible exactly (spec §5.3 rows 1-3) ----------------------

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

// --- the closed loop (spec §5.3 last row: qualitative, on a self-consistent plant) --------

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

TEST(Seed002ClosedLoop, UkfAgainstEkfOn22To25mmSteps) {
  // (iii) Fig. 19 compares UKF and EKF for references in 22-25 mm. Same model, Q, R and
  // samples; the loop is fed by the UKF.
  YAML::Node root = config();
  set_steps(root, 0.022, {{0.5, 0.025}, {1.0, 0.022}, {1.5, 0.025}, {2.0, 0.022}, {2.5, 0.025}, {3.0, 0.022},
                          {3.5, 0.025}, {4.0, 0.022}, {4.5, 0.025}, {5.0, 0.022}, {5.5, 0.025}});
  root["models"]["levitator"]["initial_gap_m"] = 0.022;
  root["blocks"]["ukf"]["initial_state"] = std::vector<double>{0.022, 0.0, 0.332};
  root["blocks"]["ekf"]["initial_state"] = std::vector<double>{0.022, 0.0, 0.332};
  root["blocks"]["ctrl"]["initial_output"] = 0.8923;
  double ukf_total = 0.0, ekf_total = 0.0;
  for (int seed = 1; seed <= 5; ++seed) {
    root["blocks"]["stage"]["seed"] = seed;
    const Trace tr = run(emit(root), 6.0);
    ASSERT_FALSE(tr.faulted) << tr.fault;
    ASSERT_TRUE(tr.held());
    const double ukf = tr.rms(tr.ukf, 0.2, 6.0);
    const double ekf = tr.rms(tr.ekf, 0.2, 6.0);
    ukf_total += ukf * ukf;
    ekf_total += ekf * ekf;
    std::printf("seed %d, 22-25 mm steps: UKF %.3f um, EKF %.3f um, UKF/EKF = %.5f\n", seed, ukf * 1e6, ekf * 1e6,
                ukf / ekf);
    // With alpha = 0.002 the sigma points sit 0.35 % of a sigma from the mean: the UKF is a
    // central-difference linearisation and the EKF's analytic one is the same to first order.
    EXPECT_NEAR(ukf / ekf, 1.0, 0.01);
  }
  const double ratio = std::sqrt(ukf_total / ekf_total);
  std::printf("UKF/EKF RMS over five seeds: %.5f (paper, Fig. 19: the UKF better, no numbers)\n", ratio);
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
  // Eq. 35 as printed was tuned on the massless linearisation of eq. 32 (spec §7.3): on the
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
