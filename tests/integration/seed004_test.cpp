// Gutierrez & Li (Machines 2024): the nonlinear passive observer (NPO) of 6-DOF body
// velocity on a simulated maglev stage, through the real loader: io.sim drives plant.rigid_body6
// (Table 1) with open-loop forces that produce the paper's test motions, called E1-E5 here
// (E1-E3 the 500 nm x, 250 nm y and 4 urad pitch steps of Figs. 5-7, E4 the reciprocating move
// of Figs. 8a/9, E5 the 400 nm circle of Figs. 8b/10), six capacitive gap probes
// (sensor.capacitive_gap, 60 nm rms each) are inverted by estimator.gap_pose, the Table 2
// low-pass filter (filter.biquad) smooths the pose, and estimator.npo estimates V_B from it and the
// applied force (io.sim's truth carries the plant's force readback). The paper prints no numbers
// (plots only): the pass criteria S1-S8 are set here.
//
//   S1 exactness with a perfect model     S5 E4 plateau means and sign-change latency
//   S2 convergence, W non-increasing      S6 E5 circle: amplitude r w, 90 deg between axes
//   S3 discretization at a0 T = 4          S7 nonlinear vs linear NPO at E1-E5 amplitudes
//   S4 noise: NPO beats finite difference  S8 force bias: steady velocity error a b / d
// plus the Table 2 low-pass filter against an independent computation and the shipped
// config/npo_velocity.yaml in closed loop. S7 deviates from its proposed bound on E1-E3 (see
// that test and the NPO README).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/require.hpp"

namespace {

constexpr double kRateHz = 2500.0;  // the paper's DSP runs at 2.5 kHz
constexpr double kT = 1.0 / kRateHz;
constexpr std::array<double, 6> kM{0.931, 0.931, 0.931, 1.799e-3, 1.834e-3, 3.336e-3};  // Table 1
constexpr const char* kAxisNames[6] = {"u", "v", "w", "p", "q", "r"};

using Vec6 = std::array<double, 6>;

// ---- the paper's motions, as open-loop forces -------------------------------------------------

/// A test motion: initial state and the mean acceleration over each sample interval (the DAC
/// holds F = M a over the interval, so the velocity at every sample is exactly the profile's).
struct Motion {
  std::string name;
  double duration_s = 0.0;
  Vec6 initial_pose{};
  Vec6 initial_velocity{};
  std::function<Vec6(double, double)> mean_acceleration;  // over [t0, t1]
};

/// Piecewise-constant acceleration segments: {t_start, t_end, a[6]}.
struct Segment {
  double start_s;
  double end_s;
  Vec6 acceleration;
};

std::function<Vec6(double, double)> piecewise(std::vector<Segment> segments) {
  return [segments](double t0, double t1) {
    Vec6 mean{};
    for (const Segment& s : segments) {
      const double overlap = std::max(0.0, std::min(t1, s.end_s) - std::max(t0, s.start_s));
      for (std::size_t i = 0; i < 6; ++i) mean[i] += s.acceleration[i] * overlap / (t1 - t0);
    }
    return mean;
  };
}

/// E1-E3 run together, as in the paper: 500 nm in x, 250 nm in y and 4 urad about y (pitch
/// theta), each by bang-bang acceleration over 2 x 10 ms from t = 20 ms (the paper's step shape
/// is not given).
Motion steps_e1_e3() {
  const double tau = 0.010;
  const Vec6 a{500e-9 / (tau * tau), 250e-9 / (tau * tau), 0.0, 0.0, 4e-6 / (tau * tau), 0.0};
  Vec6 minus_a{};
  for (std::size_t i = 0; i < 6; ++i) minus_a[i] = -a[i];
  Motion m;
  m.name = "E1-E3 steps";
  m.duration_s = 0.2;
  m.mean_acceleration = piecewise({{0.020, 0.020 + tau, a}, {0.020 + tau, 0.020 + 2 * tau, minus_a}});
  return m;
}

/// E4: 1 um back and forth along x at +-1 mm/s^2 with +-11.5 um/s plateaus, held 50 ms between.
constexpr double kE4Acceleration = 1e-3;
constexpr double kE4Plateau = 11.5e-6;
constexpr double kE4Ramp = kE4Plateau / kE4Acceleration;                      // 11.5 ms
constexpr double kE4Cruise = (1e-6 - kE4Plateau * kE4Ramp) / kE4Plateau;    // 75.46 ms
constexpr double kE4Start = 0.020;
constexpr double kE4Hold = 0.050;
constexpr double kE4LegS = 2 * kE4Ramp + kE4Cruise;                          // 98.5 ms
constexpr double kE4ReturnStart = kE4Start + kE4LegS + kE4Hold;

Motion reciprocating_e4() {
  auto ax = [](double a) { return Vec6{a, 0, 0, 0, 0, 0}; };
  const double a = kE4Acceleration;
  std::vector<Segment> segments;
  for (const auto& [start, sign] : {std::pair{kE4Start, 1.0}, std::pair{kE4ReturnStart, -1.0}}) {
    segments.push_back({start, start + kE4Ramp, ax(sign * a)});
    segments.push_back({start + kE4Ramp + kE4Cruise, start + kE4LegS, ax(-sign * a)});
  }
  Motion m;
  m.name = "E4 reciprocating";
  m.duration_s = kE4ReturnStart + kE4LegS + 0.030;
  m.mean_acceleration = piecewise(segments);
  return m;
}

/// E5: a 400 nm circle in XY. The paper gives no period; 0.2 s (5 Hz) makes the speed
/// r w = 12.6 um/s, like E4's plateau. The stage starts on the circle with the circle's velocity.
constexpr double kE5Radius = 400e-9;
constexpr double kE5Period = 0.2;
constexpr double kE5Omega = 2.0 * std::numbers::pi / kE5Period;

Motion circle_e5() {
  Motion m;
  m.name = "E5 circle";
  m.duration_s = 2 * kE5Period;
  m.initial_pose = {kE5Radius, 0, 0, 0, 0, 0};
  m.initial_velocity = {0, kE5Radius * kE5Omega, 0, 0, 0, 0};
  const double r = kE5Radius, w = kE5Omega;
  // x = r cos wt, y = r sin wt: the mean of -r w^2 cos over [t0, t1] is -r w (sin w t1 - sin w t0)/(t1 - t0).
  m.mean_acceleration = [r, w](double t0, double t1) {
    const double h = t1 - t0;
    return Vec6{-r * w * (std::sin(w * t1) - std::sin(w * t0)) / h, r * w * (std::cos(w * t1) - std::cos(w * t0)) / h,
                0, 0, 0, 0};
  };
  return m;
}

// ---- the pipeline ------------------------------------------------------------------------------

std::string list_text(const Vec6& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) {
    char number[32];
    std::snprintf(number, sizeof number, "%.17g", v[i]);
    s += (i ? ", " : "") + std::string(number);
  }
  return s + "]";
}

/// The Table 2 gains in SI (A0 = 1e4; estimator.npo README) and the tuning rule at 50 Hz, zeta 0.7.
const std::string kTable2 = "d0: 100, a0_per_s: 1.0e4";
const std::string kTuned = "observer_frequency_hz: 50, observer_damping: 0.7";

struct Rig {
  double noise_std_v = 0.0;  // per probe; 1.2 mV = 60 nm at 20 mV/um
  int adc_bits = 0;
  bool low_pass = false;      // the Table 2 pre-filter between gap_pose and the observers
  bool bias_feed = false;     // the observers get F from feed.told instead of the readback
  std::uint64_t seed = 1;
  /// Observers: name -> extra parameters (inside a YAML flow map).
  std::vector<std::pair<std::string, std::string>> observers;
};

std::string pipeline_yaml(const Motion& motion, const Rig& rig) {
  std::ostringstream y;
  y << "pipeline: seed004_test\nrate_hz: 2500\n"
    << "models:\n"
    << "  stage: {plugin: plant.rigid_body6, initial: " << list_text(motion.initial_pose)
    << ", initial_velocity: " << list_text(motion.initial_velocity) << "}\n"
    << "  gaps: {plugin: sensor.capacitive_gap}\n"
    << "blocks:\n"
    << "  board: {plugin: io.sim, plant: stage, sensors: [gaps], noise_std_v: " << rig.noise_std_v
    << ", adc_bits: " << rig.adc_bits << ", adc_range_v: 10, seed: " << rig.seed
    << ", inputs: {command: feed.force}}\n"
    << "  pose: {plugin: estimator.gap_pose, model: gaps, noise_std_v: 1.2e-3, inputs: {measurement: board.signals}}\n";
  std::string z = "pose.pose";
  if (rig.low_pass) {
    // Table 2: H(z) = l3 / (1 - 2 l1 z^-1 + l2 z^-2), l1 = 0.79954, l2 = 0.65902, l3 = 0.05994
    // (the form that gives DC gain 1).
    y << "  lpf: {plugin: filter.biquad, type: coefficients, coefficients: [0.05994, 0, 0, -1.59908, 0.65902],"
      << " inputs: {in: pose.pose}}\n";
    z = "lpf.out";
  }
  const std::string force = rig.bias_feed ? "feed.told" : "board.truth";
  for (const auto& [name, extra] : rig.observers) {
    // Zero initial error unless the observer says otherwise (S2).
    const bool own_start = extra.find("initial_velocity") != std::string::npos;
    y << "  " << name << ": {plugin: estimator.npo, model: stage, " << extra
      << (own_start ? "" : ", initial_velocity: " + list_text(motion.initial_velocity))
      << ", inputs: {measurement: " << z << ", force: " << force << "}}\n";
  }
  return y.str();
}

/// Per-cycle record of one run.
struct Trace {
  std::vector<double> t;
  std::vector<Vec6> truth_velocity;  // V_B of the plant (board.plant_state)
  std::vector<Vec6> truth_pose;
  std::vector<Vec6> force;           // applied over the interval ending at this sample
  std::vector<std::vector<Vec6>> velocity;     // per observer
  std::vector<std::vector<Vec6>> pose;         // per observer
  std::vector<std::vector<Vec6>> fd_velocity;  // per observer
  bool ok = false;
  std::string error;
};

const lode::Elements kForceElements{{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}};

/// Runs the motion; `bias` is added to the force the observers are told (only with bias_feed).
Trace run(const Motion& motion, const Rig& rig, const Vec6& bias = {}) {
  Trace tr;
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  std::vector<std::pair<std::string, lode::Elements>> feeds{{"force", kForceElements}};
  if (rig.bias_feed) feeds.push_back({"told", kForceElements});
  auto p = lode::Pipeline::load_text(pipeline_yaml(motion, rig), "seed004_test.yaml", registry, diagnostics, feeds);
  if (!p) {
    tr.error = diagnostics.format();
    return tr;
  }
  if (!p->activate()) {
    tr.error = "activate failed";
    return tr;
  }
  double* command = const_cast<double*>(p->signal("feed.force")->data);
  double* told = rig.bias_feed ? const_cast<double*>(p->signal("feed.told")->data) : nullptr;
  const double* state = p->signal("board.plant_state")->data;
  const double* truth = p->signal("board.truth")->data;
  std::vector<const double*> velocity, pose, fd;
  for (const auto& [name, extra] : rig.observers) {
    velocity.push_back(p->signal(name + ".velocity")->data);
    pose.push_back(p->signal(name + ".pose")->data);
    fd.push_back(p->signal(name + ".fd_velocity")->data);
  }
  tr.velocity.resize(velocity.size());
  tr.pose.resize(velocity.size());
  tr.fd_velocity.resize(velocity.size());
  const auto cycles = static_cast<std::uint64_t>(std::llround(motion.duration_s * kRateHz));
  Vec6 previous{};
  for (std::uint64_t k = 0; k < cycles; ++k) {
    const double t = static_cast<double>(k) * kT;
    const Vec6 a = motion.mean_acceleration(t, t + kT);
    for (std::size_t i = 0; i < 6; ++i) {
      command[i] = kM[i] * a[i];  // applied over [t, t + T] by the board's write phase
      if (told != nullptr) told[i] = previous[i] + bias[i];  // what moved the stage over [t - T, t], biased
    }
    lode::Tick tick;
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * 400000;
    tick.dt_s = kT;
    const auto result = p->run_cycle(tick, false);
    if (result.status != lode::StepStatus::ok) {
      tr.error = "fault in op " + std::to_string(result.failed_op) + ": " +
                 p->ops()[static_cast<std::size_t>(result.failed_op)].block->fault_reason();
      return tr;
    }
    Vec6 v{}, x{}, f{};
    for (std::size_t i = 0; i < 6; ++i) {
      v[i] = state[6 + i];
      x[i] = state[i];
      f[i] = truth[6 + i];
      previous[i] = command[i];
    }
    tr.t.push_back(t);
    tr.truth_velocity.push_back(v);
    tr.truth_pose.push_back(x);
    tr.force.push_back(f);
    for (std::size_t o = 0; o < velocity.size(); ++o) {
      Vec6 ve{}, pe{}, fe{};
      for (std::size_t i = 0; i < 6; ++i) {
        ve[i] = velocity[o][i];
        pe[i] = pose[o][i];
        fe[i] = fd[o][i];
      }
      tr.velocity[o].push_back(ve);
      tr.pose[o].push_back(pe);
      tr.fd_velocity[o].push_back(fe);
    }
  }
  p->deactivate();
  tr.ok = true;
  return tr;
}

/// max_k |a_k - b_k| over the translational (0-2) or rotational (3-5) elements.
double max_difference(const std::vector<Vec6>& a, const std::vector<Vec6>& b, bool rotation, std::size_t from = 0) {
  double worst = 0.0;
  for (std::size_t k = from; k < a.size(); ++k) {
    for (std::size_t i = rotation ? 3 : 0; i < (rotation ? 6u : 3u); ++i) worst = std::max(worst, std::abs(a[k][i] - b[k][i]));
  }
  return worst;
}

double max_magnitude(const std::vector<Vec6>& a, bool rotation) {
  double worst = 0.0;
  for (const Vec6& v : a) {
    for (std::size_t i = rotation ? 3 : 0; i < (rotation ? 6u : 3u); ++i) worst = std::max(worst, std::abs(v[i]));
  }
  return worst;
}

double rms_difference(const std::vector<Vec6>& a, const std::vector<Vec6>& b, std::size_t axis, std::size_t from) {
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t k = from; k < a.size(); ++k, ++n) sum += (a[k][axis] - b[k][axis]) * (a[k][axis] - b[k][axis]);
  return std::sqrt(sum / static_cast<double>(n));
}

#define REQUIRE_CHAIN() \
  LODE_REQUIRE_PLUGINS("io.sim", "plant.rigid_body6", "sensor.capacitive_gap", "estimator.gap_pose", "estimator.npo")
#define REQUIRE_LPF() LODE_REQUIRE_PLUGINS("filter.biquad")

std::vector<Motion> all_motions() { return {steps_e1_e3(), reciprocating_e4(), circle_e5()}; }

// ---- S1: exactness with a perfect model --------------------------------------------------------

// Noise-free Z (the gaps inverted by gap_pose, no filter), the exact applied F, zero initial error:
// |v^ - v| <= 1e-6 relative on E1-E5 for every gain set and both stable integrators.
TEST(Seed004, S1ExactWithAPerfectModel) {
  REQUIRE_CHAIN();
  Rig rig;
  rig.observers = {{"table2", kTable2},
                     {"tuned", kTuned},
                     {"table2_implicit", kTable2 + ", integrator: backward_euler"},
                     {"table2_small_a", "d0: 100, a0_per_s: 1.0e-4"}};  // the other reading of A0 (npo README)
  for (const Motion& motion : all_motions()) {
    const Trace tr = run(motion, rig);
    ASSERT_TRUE(tr.ok) << tr.error;
    const double v_scale = max_magnitude(tr.truth_velocity, false);
    const double w_scale = max_magnitude(tr.truth_velocity, true);
    for (std::size_t o = 0; o < rig.observers.size(); ++o) {
      const double dv = max_difference(tr.velocity[o], tr.truth_velocity, false) / v_scale;
      const double dw = w_scale > 0.0 ? max_difference(tr.velocity[o], tr.truth_velocity, true) / w_scale : 0.0;
      std::printf("S1 %-16s %-16s max|v^-v|/max|v|: translation %.2e, rotation %.2e (criterion 1e-6)\n",
                  motion.name.c_str(), rig.observers[o].first.c_str(), dv, dw);
      EXPECT_LT(dv, 1e-6) << motion.name << " " << rig.observers[o].first;
      EXPECT_LT(dw, 1e-6) << motion.name << " " << rig.observers[o].first;
    }
  }
}


// ---- S2: convergence from random initial errors ------------------------------------------------

struct Gains {
  std::string name;
  std::string yaml;
  Vec6 d{};
  Vec6 a{};
};

Gains table2_gains() {
  Gains g{"table2", kTable2, {}, {}};
  g.d.fill(100.0);
  g.a.fill(1e4);
  return g;
}

Gains tuned_gains() {
  const double w = 2.0 * std::numbers::pi * 50.0;
  Gains g{"tuned", kTuned, {}, {}};
  for (std::size_t i = 0; i < 6; ++i) {
    g.d[i] = kM[i] * w * w;  // the tuning rule (estimator.npo README)
    g.a[i] = 2.0 * 0.7 * w;
  }
  return g;
}

/// The slow (or the only real part of a complex) root of m s^2 + m a s + d [1/s].
double slow_rate(double m, double d, double a) {
  const double disc = a * a - 4.0 * d / m;
  return disc >= 0.0 ? 0.5 * (-a + std::sqrt(disc)) : -0.5 * a;
}

/// W = 1/2 V~' M V~ + 1/2 P~' D0 P~ (the composite Lyapunov function, estimator.npo README) at
/// every sample.
std::vector<double> composite_w(const Trace& tr, std::size_t observer, const Vec6& d) {
  std::vector<double> w;
  for (std::size_t k = 0; k < tr.t.size(); ++k) {
    double sum = 0.0;
    for (std::size_t i = 0; i < 6; ++i) {
      const double dv = tr.truth_velocity[k][i] - tr.velocity[observer][k][i];
      const double dp = tr.truth_pose[k][i] - tr.pose[observer][k][i];
      sum += 0.5 * kM[i] * dv * dv + 0.5 * d[i] * dp * dp;
    }
    w.push_back(sum);
  }
  return w;
}

// From random initial errors (V~, P~), W never increases and the errors decay at the derived
// rates: Table 2 gains -0.0107 (translation), -5.56, -5.46, -3.00 1/s (rotations); tuned
// gains: envelope zeta w = 220 1/s.
TEST(Seed004, S2ConvergenceFromRandomInitialErrors) {
  REQUIRE_CHAIN();
  std::mt19937_64 rng(4);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (const Motion& motion : {Motion{"at rest", 2.0, {}, {}, [](double, double) { return Vec6{}; }}, steps_e1_e3()}) {
    for (const Gains& gains : {table2_gains(), tuned_gains()}) {
      Vec6 p0{}, v0{};
      for (std::size_t i = 0; i < 6; ++i) {
        // 1 um, 10 urad, 10 um/s, 10 urad/s: the experiments' scale. Much larger rate
        // errors make the observer's own Coriolis term C(V^)V^ (~ rate error x velocity error)
        // visible against the 93 s translational mode and bias its fitted rate by a few percent.
        p0[i] = motion.initial_pose[i] + (i < 3 ? 1e-6 : 1e-5) * unit(rng);
        v0[i] = motion.initial_velocity[i] + 1e-5 * unit(rng);
      }
      Rig rig;
      rig.observers = {{gains.name, gains.yaml + ", initialize_from_first_measurement: false, initial_pose: " +
                                        list_text(p0) + ", initial_velocity: " + list_text(v0)}};
      Motion longer = motion;
      longer.duration_s = std::max(motion.duration_s, 2.0);
      const Trace tr = run(longer, rig);
      ASSERT_TRUE(tr.ok) << tr.error;
      const std::vector<double> w = composite_w(tr, 0, gains.d);
      std::size_t rises = 0;
      double worst_rise = 0.0;
      for (std::size_t k = 1; k < w.size(); ++k) {
        const double rise = (w[k] - w[k - 1]) / w[0];
        if (rise > 1e-12) ++rises;
        worst_rise = std::max(worst_rise, rise);
      }
      std::printf("S2 %-10s %-7s W0 = %.3g J, W(2 s)/W0 = %.3g, largest one-step rise %.2g W0 (%zu rises > 1e-12)\n",
                  motion.name.c_str(), gains.name.c_str(), w[0], w.back() / w[0], worst_rise, rises);
      EXPECT_EQ(rises, 0u) << motion.name << " " << gains.name;
      EXPECT_LT(w.back(), w[0]) << motion.name << " " << gains.name;

      // Decay rates from the velocity errors.
      if (gains.name == "table2") {
        // After the fast mode (-1e4 1/s) has gone, each axis decays as e^{s_slow t}: fit 0.1 ... 2 s.
        const std::size_t k1 = static_cast<std::size_t>(0.1 * kRateHz), k2 = w.size() - 1;
        for (std::size_t i = 0; i < 6; ++i) {
          const double e1 = tr.truth_velocity[k1][i] - tr.velocity[0][k1][i];
          const double e2 = tr.truth_velocity[k2][i] - tr.velocity[0][k2][i];
          const double measured = std::log(std::abs(e2 / e1)) / (tr.t[k2] - tr.t[k1]);
          const double expected = slow_rate(kM[i], gains.d[i], gains.a[i]);
          std::printf("   %s: decay %.5g 1/s (tau %.4g s), derived %.5g 1/s\n", kAxisNames[i], measured, -1.0 / measured,
                      expected);
          EXPECT_NEAR(measured / expected, 1.0, 0.01) << kAxisNames[i];
        }
      } else {
        // Complex pair: ln W falls at 2 zeta w on average; regress over the first 20 ms.
        const std::size_t n = static_cast<std::size_t>(0.020 * kRateHz);
        double st = 0.0, sy = 0.0, stt = 0.0, sty = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
          const double y = std::log(w[k]);
          st += tr.t[k];
          sy += y;
          stt += tr.t[k] * tr.t[k];
          sty += tr.t[k] * y;
        }
        const double slope = (n * sty - st * sy) / (n * stt - st * st);
        const double expected = 2.0 * 0.7 * 2.0 * std::numbers::pi * 50.0;
        std::printf("   ln W slope %.4g 1/s over 20 ms, 2 zeta w = %.4g 1/s (envelope tau %.3g ms)\n", slope, -expected,
                    -2e3 / slope);
        EXPECT_NEAR(-slope / expected, 1.0, 0.10);
      }
    }
  }
}

// ---- S3: discretization at a0 T = 4 -------------------------------------------------------------

// The exact and the implicit updates stay bounded at A0 = 1e4, T = 0.4 ms: W never exceeds W0, so
// no velocity error exceeds sqrt(2 W0 / M_i); forward Euler (eigenvalue 1 - aT = -3) is refused
// when the pipeline loads.
TEST(Seed004, S3StiffGainsNeedAnExactOrImplicitUpdate) {
  REQUIRE_CHAIN();
  const Vec6 p0{1e-6, -1e-6, 5e-7, 1e-5, -1e-5, 2e-5};
  const Vec6 v0{1e-5, 2e-5, -1e-5, 1e-4, 2e-4, -1e-4};
  const std::string start = ", initialize_from_first_measurement: false, initial_pose: " + list_text(p0) +
                            ", initial_velocity: " + list_text(v0);
  Rig rig;
  rig.observers = {{"exact", kTable2 + start}, {"implicit", kTable2 + ", integrator: backward_euler" + start}};
  Motion rest{"at rest", 1.0, {}, {}, [](double, double) { return Vec6{}; }};
  const Trace tr = run(rest, rig);
  ASSERT_TRUE(tr.ok) << tr.error;
  for (std::size_t o = 0; o < 2; ++o) {
    const std::vector<double> w = composite_w(tr, o, table2_gains().d);
    double w_max = 0.0;
    std::size_t rises = 0;
    for (std::size_t k = 0; k < w.size(); ++k) {
      w_max = std::max(w_max, w[k]);
      if (k > 0 && w[k] > w[k - 1] * (1.0 + 1e-12)) ++rises;
    }
    bool within = true;
    for (std::size_t k = 0; k < tr.t.size(); ++k) {
      for (std::size_t i = 0; i < 6; ++i) {
        const double error = std::abs(tr.truth_velocity[k][i] - tr.velocity[o][k][i]);
        within = within && std::isfinite(error) && error <= std::sqrt(2.0 * w[0] / kM[i]) * (1.0 + 1e-9);
      }
    }
    std::printf("S3 %-8s a0 T = 4: max W / W0 = %.6f, W(1 s) / W0 = %.4g, %zu one-step rises; every |v~_i| <= "
                "sqrt(2 W0 / M_i): %s\n",
                rig.observers[o].first.c_str(), w_max / w[0], w.back() / w[0], rises, within ? "yes" : "no");
    EXPECT_TRUE(within) << rig.observers[o].first;
    EXPECT_LE(w_max, w[0] * (1.0 + 1e-9)) << rig.observers[o].first;
    EXPECT_LT(w.back(), w[0]) << rig.observers[o].first;
  }

  Rig euler;
  euler.observers = {{"euler", kTable2 + ", integrator: forward_euler"}};
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  auto p = lode::Pipeline::load_text(pipeline_yaml(rest, euler), "seed004_s3.yaml", registry, diagnostics,
                                     {{"force", kForceElements}});
  EXPECT_EQ(p, nullptr);
  const std::string why = diagnostics.format();
  std::printf("S3 forward Euler refused: %s\n", why.c_str());
  EXPECT_NE(why.find("forward_euler is unstable"), std::string::npos) << why;
  EXPECT_NE(why.find("a0 T = 4"), std::string::npos) << why;
  EXPECT_NE(why.find("-3"), std::string::npos) << why;
}

// ---- S7: nonlinear vs linear observer ------------------------------------------------------------

// At E1-E5 amplitudes (um, urad, ~10 um/s) the full NPO (C(V^), R_BF, E) and six decoupled linear
// observers agree to < 1e-6 relative; a fast spin (1 rad/s about z while moving at 1 mm/s) is
// where they part: the linear one cannot follow the body-frame velocity turning.
TEST(Seed004, S7NonlinearAndLinearObserversAgreeAtThePapersAmplitudes) {
  REQUIRE_CHAIN();
  Rig rig;
  rig.observers = {{"nl_table2", kTable2},
                   {"lin_table2", kTable2 + ", dynamics: linear"},
                   {"nl_tuned", kTuned},
                   {"lin_tuned", kTuned + ", dynamics: linear"}};
  for (const Motion& motion : all_motions()) {
    const Trace tr = run(motion, rig);
    ASSERT_TRUE(tr.ok) << tr.error;
    const double v_scale = max_magnitude(tr.truth_velocity, false);
    const double w_scale = max_magnitude(tr.truth_velocity, true);
    // The frame effect of a tilt: a body pitched by theta moving at u along fixed x has a body-frame
    // w ~ theta u that the linear observer (J = I) does not see. Its bound relative to max |v|:
    // max |tilt| x max horizontal speed / max |v|.
    double max_tilt = 0.0, max_speed = 0.0;
    for (std::size_t k = 0; k < tr.t.size(); ++k) {
      max_tilt = std::max({max_tilt, std::abs(tr.truth_pose[k][3]), std::abs(tr.truth_pose[k][4])});
      max_speed = std::max(max_speed, std::hypot(tr.truth_velocity[k][0], tr.truth_velocity[k][1]));
    }
    const double tilt_effect = max_tilt * max_speed / v_scale;
    for (std::size_t o = 0; o < 4; o += 2) {
      const double dv = max_difference(tr.velocity[o], tr.velocity[o + 1], false) / v_scale;
      const double dw = w_scale > 0.0 ? max_difference(tr.velocity[o], tr.velocity[o + 1], true) / w_scale : 0.0;
      const double nl_error = max_difference(tr.velocity[o], tr.truth_velocity, false) / v_scale;
      const double lin_error = max_difference(tr.velocity[o + 1], tr.truth_velocity, false) / v_scale;
      std::printf("S7 %-16s %-6s max|v^_nl - v^_lin|/max|v|: translation %.2e, rotation %.2e (criterion 1e-6); "
                  "vs truth: nonlinear %.2e, linear %.2e; max tilt x max speed / max|v| = %.2e\n",
                  motion.name.c_str(), o == 0 ? "table2" : "tuned", dv, dw, nl_error, lin_error, tilt_effect);
      EXPECT_LT(dw, 1e-6) << motion.name;
      EXPECT_LT(nl_error, 1e-9) << motion.name;
      if (tilt_effect == 0.0) {
        EXPECT_LT(dv, 1e-6) << motion.name;
      } else {
        // DEVIATION from S7's bound (< 1e-6): E3's 4 urad pitch during E1's 50 um/s move gives a
        // body-frame w of theta u = 2e-10 m/s, 4e-6 of max |v|; the nonlinear observer follows it
        // (it is the true V_B), the linear one cannot. The difference is that frame effect, no more.
        EXPECT_GT(dv, 0.1 * tilt_effect) << motion.name;
        EXPECT_LT(dv, tilt_effect) << motion.name;
      }
    }
  }
  // High rate: the linear observer is wrong by a large fraction, the nonlinear one stays exact.
  Motion spin{"spin 1 rad/s", 0.5, {}, {1e-3, 0, 0, 0, 0, 1.0}, [](double, double) { return Vec6{}; }};
  const Trace tr = run(spin, rig);
  ASSERT_TRUE(tr.ok) << tr.error;
  const double v_scale = max_magnitude(tr.truth_velocity, false);
  const double nl = max_difference(tr.velocity[2], tr.truth_velocity, false) / v_scale;
  const double lin = max_difference(tr.velocity[3], tr.truth_velocity, false) / v_scale;
  std::printf("S7 %-16s tuned: nonlinear max|v^-v|/max|v| %.2e, linear %.2e\n", spin.name.c_str(), nl, lin);
  EXPECT_LT(nl, 1e-9);
  EXPECT_GT(lin, 0.1);
}

// ---- S8: force-bias sensitivity --------------------------------------------------------------------

/// Continuous response of the per-axis error (p~, v~) to a constant force bias b from zero error:
/// x' = A_e x + [0, -b/m], x(t) = (e^{A_e t} - I) A_e^-1 [0, -b/m]  (per-axis error dynamics).
Eigen::Vector2d bias_transient(double m, double d, double a, double b, double t) {
  Eigen::Matrix2d ae;
  ae << -a, 1.0, -d / m, 0.0;
  const Eigen::EigenSolver<Eigen::Matrix2d> solver(ae);
  const Eigen::Matrix2cd v = solver.eigenvectors();
  Eigen::Matrix2cd expo = Eigen::Matrix2cd::Zero();
  for (int i = 0; i < 2; ++i) expo(i, i) = std::exp(solver.eigenvalues()(i) * t);
  const Eigen::Matrix2d phi = (v * expo * v.inverse()).real();
  return (phi - Eigen::Matrix2d::Identity()) * ae.inverse() * Eigen::Vector2d(0.0, -b / m);
}

// A constant bias b on the force the observer is told leaves the steady velocity error a b / d
// per axis. With the Table 2 gains read in SI that is 100 m/s per newton: the paper states no
// units for its gains (estimator.npo README).
TEST(Seed004, S8ForceBiasLeavesVelocityErrorAbOverD) {
  REQUIRE_CHAIN();
  const Vec6 bias{1e-6, -2e-6, 1.5e-6, 1e-9, -2e-9, 1.5e-9};  // 1 uN and 1 nN*m scale
  Rig rig;
  rig.bias_feed = true;
  rig.observers = {{"table2", kTable2}, {"tuned", kTuned}};
  Motion rest{"at rest", 3.0, {}, {}, [](double, double) { return Vec6{}; }};
  const Trace tr = run(rest, rig, bias);
  ASSERT_TRUE(tr.ok) << tr.error;
  const std::size_t last = tr.t.size() - 1;
  const double t_end = tr.t[last];
  const std::vector<Gains> gains{table2_gains(), tuned_gains()};
  for (std::size_t o = 0; o < 2; ++o) {
    for (std::size_t i = 0; i < 6; ++i) {
      const double error = tr.velocity[o][last][i] - tr.truth_velocity[last][i];  // v^ - v = a b / d
      const double steady = gains[o].a[i] * bias[i] / gains[o].d[i];
      // Where the slow mode has not settled in 3 s (Table 2 translation: tau = 93 s), compare with
      // the continuous transient; elsewhere with the steady state itself.
      const double transient = -bias_transient(kM[i], gains[o].d[i], gains[o].a[i], bias[i], t_end)(1);
      std::printf("S8 %-6s %s: v^ - v = %.5g, a b/d = %.5g (%.4f of it), continuous transient at 3 s %.5g%s\n",
                  gains[o].name.c_str(), kAxisNames[i], error, steady, error / steady, transient,
                  std::abs(transient / steady - 1.0) < 1e-3 ? "" : "  (not settled)");
      EXPECT_NEAR(error / transient, 1.0, 2e-3) << gains[o].name << " " << kAxisNames[i];
      if (std::abs(transient / steady - 1.0) < 1e-3) {
        EXPECT_NEAR(error / steady, 1.0, 2e-3);
      }
    }
  }
  std::printf("S8 Table 2 gains in SI: a/d = %.0f (m/s)/N on x, y, z: a 1 mN force-model error -> %.2g m/s, "
              "%.0f x the E4 plateau\n",
              1e4 / 100.0, 1e4 / 100.0 * 1e-3, 1e4 / 100.0 * 1e-3 / kE4Plateau);
}


// ---- S4-S6: with sensor noise and the Table 2 low-pass filter ------------------------------------

/// 60 nm rms per probe (1.2 mV at 20 mV/um; the paper's estimate), a 16-bit +-10 V converter
/// (LSB 15 nm), the Table 2 pre-filter, and the finite difference of its output (the paper's
/// "measured velocity").
Rig noisy_rig() {
  Rig rig;
  rig.noise_std_v = 1.2e-3;
  rig.adc_bits = 16;
  rig.low_pass = true;
  rig.seed = 4;
  rig.observers = {{"table2", kTable2}, {"tuned", kTuned}};
  return rig;
}

/// Statistics start after the filter and observer start-up (E5 starts on the circle, so the
/// low-pass filter, which starts from 0, needs a few ms and the tuned observer ~20 ms).
std::size_t settled_index(const Motion& motion) {
  return static_cast<std::size_t>((motion.name == "E5 circle" ? 0.1 : 0.01) * kRateHz);
}

double rms_over(const std::vector<Vec6>& a, const std::vector<Vec6>& b, bool rotation, std::size_t from) {
  double sum = 0.0;
  for (std::size_t i = rotation ? 3 : 0; i < (rotation ? 6u : 3u); ++i) {
    const double r = rms_difference(a, b, i, from);
    sum += r * r;
  }
  return std::sqrt(sum / 3.0);
}

// S4: RMS(v^ - v) < RMS(v_FD - v) on E1-E5 with noise, per group of axes.
TEST(Seed004, S4ObserverBeatsTheFiniteDifference) {
  REQUIRE_CHAIN();
  REQUIRE_LPF();
  const Rig rig = noisy_rig();
  for (const Motion& motion : all_motions()) {
    const Trace tr = run(motion, rig);
    ASSERT_TRUE(tr.ok) << tr.error;
    const std::size_t from = settled_index(motion);
    const double fd_v = rms_over(tr.fd_velocity[0], tr.truth_velocity, false, from);
    const double fd_w = rms_over(tr.fd_velocity[0], tr.truth_velocity, true, from);
    for (std::size_t o = 0; o < rig.observers.size(); ++o) {
      const double npo_v = rms_over(tr.velocity[o], tr.truth_velocity, false, from);
      const double npo_w = rms_over(tr.velocity[o], tr.truth_velocity, true, from);
      std::printf("S4 %-16s %-6s RMS error: NPO %.3g um/s vs FD %.3g um/s (x, y, z); NPO %.3g vs FD %.3g urad/s "
                  "(phi, theta, psi)\n",
                  motion.name.c_str(), rig.observers[o].first.c_str(), npo_v * 1e6, fd_v * 1e6, npo_w * 1e6,
                  fd_w * 1e6);
      EXPECT_LT(npo_v, fd_v) << motion.name << " " << rig.observers[o].first;
      EXPECT_LT(npo_w, fd_w) << motion.name << " " << rig.observers[o].first;
    }
  }
}

/// First time after `from` at which sign * y[axis] exceeds `level`.
double first_crossing(const Trace& tr, const std::vector<Vec6>& y, std::size_t axis, double from_s, double level,
                      double sign) {
  for (std::size_t k = 0; k < tr.t.size(); ++k) {
    if (tr.t[k] >= from_s && sign * y[k][axis] > level) return tr.t[k];
  }
  return NAN;
}

// S5: E4 plateau means within +-10 % of +-11.5 um/s; the sign change seen within one ramp time
// (11.5 ms) of the truth's. "Seen" is the first sample beyond half the plateau in the new
// direction, for the estimate and for the truth alike (a noisy estimate may get there early).
TEST(Seed004, S5ReciprocatingPlateausAndSignChange) {
  REQUIRE_CHAIN();
  REQUIRE_LPF();
  const Rig rig = noisy_rig();
  const Motion motion = reciprocating_e4();
  const Trace tr = run(motion, rig);
  ASSERT_TRUE(tr.ok) << tr.error;
  auto plateau_mean = [&](const std::vector<Vec6>& y, double leg_start) {
    double sum = 0.0;
    int n = 0;
    for (std::size_t k = 0; k < tr.t.size(); ++k) {
      if (tr.t[k] >= leg_start + kE4Ramp && tr.t[k] < leg_start + kE4Ramp + kE4Cruise) {
        sum += y[k][0];
        ++n;
      }
    }
    return sum / n;
  };
  const double level = 0.5 * kE4Plateau;
  for (std::size_t o = 0; o < rig.observers.size(); ++o) {
    const double up = plateau_mean(tr.velocity[o], kE4Start);
    const double down = plateau_mean(tr.velocity[o], kE4ReturnStart);
    const double fd_up = plateau_mean(tr.fd_velocity[o], kE4Start);
    const double fd_down = plateau_mean(tr.fd_velocity[o], kE4ReturnStart);
    const double true_reverse = first_crossing(tr, tr.truth_velocity, 0, kE4ReturnStart, level, -1.0);
    const double seen_reverse = first_crossing(tr, tr.velocity[o], 0, kE4ReturnStart, level, -1.0);
    const double true_start = first_crossing(tr, tr.truth_velocity, 0, kE4Start, level, 1.0);
    const double seen_start = first_crossing(tr, tr.velocity[o], 0, kE4Start, level, 1.0);
    std::printf("S5 %-6s plateaus %+.3f / %+.3f um/s (FD %+.3f / %+.3f; want +-11.5 +-10 %%), start seen %.2f ms and "
                "reversal %.2f ms after the truth (limit 11.5 ms)\n",
                rig.observers[o].first.c_str(), up * 1e6, down * 1e6, fd_up * 1e6, fd_down * 1e6,
                (seen_start - true_start) * 1e3, (seen_reverse - true_reverse) * 1e3);
    EXPECT_NEAR(up, kE4Plateau, 0.1 * kE4Plateau);
    EXPECT_NEAR(down, -kE4Plateau, 0.1 * kE4Plateau);
    EXPECT_LE(std::abs(seen_reverse - true_reverse), kE4Ramp);
    EXPECT_LE(std::abs(seen_start - true_start), kE4Ramp);
  }
}

/// Amplitude and phase of y[axis] at w over [t0, t0 + one period] by projection.
std::pair<double, double> harmonic(const Trace& tr, const std::vector<Vec6>& y, std::size_t axis, double t0) {
  double c = 0.0, s = 0.0;
  int n = 0;
  for (std::size_t k = 0; k < tr.t.size(); ++k) {
    if (tr.t[k] >= t0 && tr.t[k] < t0 + kE5Period - 1e-9) {
      c += y[k][axis] * std::cos(kE5Omega * tr.t[k]);
      s += y[k][axis] * std::sin(kE5Omega * tr.t[k]);
      ++n;
    }
  }
  c *= 2.0 / n;
  s *= 2.0 / n;
  return {std::hypot(c, s), std::atan2(c, s)};  // y ~ A sin(w t + phase)
}

// S6: v^_x and v^_y have amplitude r w (+-10 %) and are 90 deg apart on a 400 nm circle at 5 Hz.
TEST(Seed004, S6CircleAmplitudeAndQuadrature) {
  REQUIRE_CHAIN();
  REQUIRE_LPF();
  const Rig rig = noisy_rig();
  const Motion motion = circle_e5();
  const Trace tr = run(motion, rig);
  ASSERT_TRUE(tr.ok) << tr.error;
  const double expected = kE5Radius * kE5Omega;
  const double t0 = kE5Period;  // the second revolution
  auto report = [&](const char* what, const std::vector<Vec6>& y, bool check) {
    const auto [ax, px] = harmonic(tr, y, 0, t0);
    const auto [ay, py] = harmonic(tr, y, 1, t0);
    double quadrature = (py - px) * 180.0 / std::numbers::pi;
    while (quadrature > 180.0) quadrature -= 360.0;
    while (quadrature < -180.0) quadrature += 360.0;
    std::printf("S6 %-10s |v_x| %.4f, |v_y| %.4f um/s (r w = %.4f, +-10 %%), phase y - x %.3f deg (-90: counter-clockwise)\n", what,
                ax * 1e6, ay * 1e6, expected * 1e6, quadrature);
    if (check) {
      EXPECT_NEAR(ax / expected, 1.0, 0.10) << what;
      EXPECT_NEAR(ay / expected, 1.0, 0.10) << what;
      // Counter-clockwise (x = r cos wt, y = r sin wt): v_x = r w sin(wt + 180 deg) leads
      // v_y = r w sin(wt + 90 deg) by 90 deg, so y - x = -90 in harmonic()'s convention.
      EXPECT_NEAR(quadrature, -90.0, 5.0) << what;
    }
  };
  report("truth", tr.truth_velocity, true);
  for (std::size_t o = 0; o < rig.observers.size(); ++o) report(rig.observers[o].first.c_str(), tr.velocity[o], true);
  report("FD", tr.fd_velocity[0], false);
}


// ---- the shipped pipeline ---------------------------------------------------------------------------

// config/npo_velocity.yaml closed loop: E1-E3 steps tracked (500 nm, 250 nm, 4 urad), the NPO's
// velocity error far below the finite difference's, and describe() shows the derived poles.
TEST(Seed004, ShippedPipelineTracksTheStepsWithTheObserverInTheLoop) {
  REQUIRE_CHAIN();
  REQUIRE_LPF();
  LODE_REQUIRE_PLUGINS("controller.lq_integral", "source.step");
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  auto p = lode::Pipeline::load_file(LODE_SOURCE_DIR "/config/npo_velocity.yaml", registry, diagnostics);
  ASSERT_TRUE(p) << diagnostics.format();
  ASSERT_TRUE(p->activate());
  const double* state = p->signal("board.plant_state")->data;
  const double* estimate = p->signal("npo.state")->data;
  const double* fd = p->signal("npo.fd_velocity")->data;
  const auto cycles = static_cast<std::uint64_t>(std::llround(*p->default_duration_s() * p->rate_hz()));
  Vec6 held{};  // truth pose averaged over 0.4-0.6 s (after the step at 0.1 s)
  int held_n = 0;
  std::array<double, 2> npo_sq{}, fd_sq{};
  int n = 0;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    lode::Tick tick;
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    tick.dt_s = 1.0 / p->rate_hz();
    const auto result = p->run_cycle(tick, false);
    ASSERT_EQ(result.status, lode::StepStatus::ok) << p->ops()[static_cast<std::size_t>(result.failed_op)].block->fault_reason();
    const double t = static_cast<double>(k) / p->rate_hz();
    if (t >= 0.4 && t < 0.6) {
      for (std::size_t i = 0; i < 6; ++i) held[i] += state[i];
      ++held_n;
    }
    if (t >= 0.02) {
      for (std::size_t i = 0; i < 6; ++i) {
        const std::size_t group = i < 3 ? 0 : 1;
        npo_sq[group] += std::pow(estimate[6 + i] - state[6 + i], 2);
        fd_sq[group] += std::pow(fd[i] - state[6 + i], 2);
      }
      ++n;
    }
  }
  for (double& v : held) v /= held_n;
  const Vec6 target{500e-9, 250e-9, 0, 0, 4e-6, 0};
  std::printf("pipeline: held pose x %.1f nm, y %.1f nm, z %.1f nm, theta %.3f urad (targets 500, 250, 0, 4)\n",
              held[0] * 1e9, held[1] * 1e9, held[2] * 1e9, held[4] * 1e6);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(held[i], target[i], 15e-9) << i;
  for (std::size_t i = 3; i < 6; ++i) EXPECT_NEAR(held[i], target[i], 0.3e-6) << i;
  const double npo_v = std::sqrt(npo_sq[0] / (3.0 * n)), fd_v = std::sqrt(fd_sq[0] / (3.0 * n));
  const double npo_w = std::sqrt(npo_sq[1] / (3.0 * n)), fd_w = std::sqrt(fd_sq[1] / (3.0 * n));
  std::printf("pipeline: velocity error rms NPO %.3g um/s vs FD %.3g um/s; NPO %.3g vs FD %.3g urad/s\n", npo_v * 1e6,
              fd_v * 1e6, npo_w * 1e6, fd_w * 1e6);
  EXPECT_LT(npo_v, 0.01 * fd_v);
  EXPECT_LT(npo_w, 0.1 * fd_w);

  const lode::Json described = p->describe();
  const lode::Json* npo = described.find("blocks")->find("npo")->find("derived");
  ASSERT_NE(npo, nullptr);
  const auto& x_axis = npo->find("axes")->elements()[0];
  const double slow = std::max(x_axis.find("error_poles_rad_s")->elements()[0].find("re")->as_number(),
                               x_axis.find("error_poles_rad_s")->elements()[1].find("re")->as_number());
  EXPECT_NEAR(slow, -0.0107, 1e-4);  // derived for the Table 2 gains in SI
  p->deactivate();
}


// ---- the Table 2 pre-filter ---------------------------------------------------------------------

// filter.biquad with the Table 2 coefficients, driven with sines: the gains of a table computed
// independently (-0.01 dB at 10 Hz ... -33.8 dB at 1 kHz), unity DC gain, -3 dB near 99.3 Hz
// (not the 120 Hz the paper says it chose) and a group delay of about 4.7 samples at low
// frequency.
TEST(Seed004, Table2LowPassFilterMatchesAnIndependentTable) {
  REQUIRE_LPF();
  auto measure = [](double f_hz, double& gain, double& delay_samples) {
    lode::testing::BlockHarness h("filter.biquad",
                                  "type: coefficients\ncoefficients: [0.05994, 0, 0, -1.59908, 0.65902]\n", kRateHz);
    h.feed("in", {{"x", "m"}});
    if (!h.configure() || !h.activate()) return false;
    const double w = 2.0 * std::numbers::pi * f_hz;
    // Settle for 0.5 s, then project over an integer number of periods (>= 0.5 s).
    const int settle = static_cast<int>(0.5 * kRateHz);
    const int periods = std::max(1, static_cast<int>(std::ceil(0.5 * f_hz)));
    const int n = static_cast<int>(std::llround(periods * kRateHz / f_hz));
    double c = 0.0, sn = 0.0;
    for (int k = 0; k < settle + n; ++k) {
      const double t = k * kT;
      h.input("in")[0] = std::sin(w * t);
      h.step();
      if (k >= settle) {
        c += h.output("out")[0] * std::cos(w * t);
        sn += h.output("out")[0] * std::sin(w * t);
      }
    }
    gain = 2.0 / n * std::hypot(c, sn);
    delay_samples = -std::atan2(c, sn) / (w * kT);
    return true;
  };
  const std::array<std::pair<double, double>, 7> table{
      {{10, -0.01}, {50, -0.49}, {100, -3.05}, {120, -4.65}, {200, -11.3}, {500, -25.5}, {1000, -33.8}}};
  for (const auto& [f, printed] : table) {
    double gain = 0.0, delay = 0.0;
    ASSERT_TRUE(measure(f, gain, delay));
    const double db = 20.0 * std::log10(gain);
    std::printf("LPF %6.0f Hz: %7.2f dB (ref: %6.2f dB)\n", f, db, printed);
    EXPECT_NEAR(db, printed, std::max(0.02, 0.005 * std::abs(printed)));
  }
  double gain = 0.0, delay = 0.0;
  ASSERT_TRUE(measure(1.0, gain, delay));
  std::printf("LPF 1 Hz: gain %.5f, group delay ~ phase delay %.2f samples (ref: 4.69 samples, 1.88 ms)\n", gain, delay);
  EXPECT_NEAR(gain, 1.0, 1e-4);
  EXPECT_NEAR(delay, 4.69, 0.05);
  // The -3 dB point by bisection on the measured response.
  double lo = 90.0, hi = 110.0;
  for (int i = 0; i < 20; ++i) {
    const double mid = 0.5 * (lo + hi);
    double g = 0.0, d = 0.0;
    ASSERT_TRUE(measure(mid, g, d));
    (20.0 * std::log10(g) > -3.0103 ? lo : hi) = mid;
  }
  std::printf("LPF -3 dB at %.1f Hz (ref: 99.3 Hz; the paper says 120 Hz)\n", 0.5 * (lo + hi));
  EXPECT_NEAR(0.5 * (lo + hi), 99.3, 0.3);
}

}  // namespace
