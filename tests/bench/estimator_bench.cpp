// What one cycle of estimator.ukf and estimator.ekf costs on the magnetic suspension of
// config/suspension_ukf.yaml (n = 3 states, one measured gap, UKF alpha = 0.002, beta = 2,
// kappa = 0, the same Q, R, x_0 and P_0): predict + update, called through the plugin as the
// pipeline calls it (the input ports written, then Block::step()).
//
//   ./build/tests/lode_estimator_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// Before/after a change to the estimators: the same binary loads the plugins from another
// build's plugin folder when LODE_PLUGIN_PATH names it, e.g.
//   LODE_PLUGIN_PATH=/path/to/other/build/plugins ./build/tests/lode_estimator_bench
//
// The samples: the magnet moved along gap(t) = 26 mm + 2 mm sin(pi t) by the coil voltage
// that the Euler model itself needs for it (inverse dynamics), the gap measured with the
// configured 0.35 mm noise (fixed seed). 4000 samples (2 s at 2 kHz), replayed in a loop
// after 2000 cycles of warm-up, so the filters run converged on consistent data.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "lode/sdk/testing/block_host.hpp"

namespace {

// config/suspension_ukf.yaml's plant (Euler discretisation, the estimators' f) and its
// measurement model.
const char* const kModels =
    "levitator: {plugin: plant.suspension, mass_kg: 6.0e-3, gravity_m_s2: 9.81, force_a_n_m4: 5.996e-9,"
    " force_b_n_m2_per_a: 4.85e-5, coil_decay_1_per_s: 165.6, coil_gain_a_per_v_s: 61.61,"
    " initial_gap_m: 0.026, process_discretization: euler}\n"
    "hall_distance: {plugin: sensor.hall_gap, output: gap}\n";

const char* const kCommon =
    "process: levitator\nmeasurement: hall_distance\n"
    "q: [5.6e-8, 1.7e-8, 7.71e-3]\nprocess_noise: per_second\nr: 1.2e-7\n"
    "initial_state: [0.026, 0.0, 0.6375]\np0: [1.0e-8, 1.0e-6, 1.0e-4]\n";

constexpr double kRateHz = 2000.0;
constexpr int kSamples = 4000;
constexpr int kWarmUp = 2000;

struct Samples {
  std::vector<double> measured_gap, gap, voltage;
};

/// The coil current that gives the gap d acceleration acc (eq. 13 and 33 solved for i).
double current_for(double d, double acc) {
  const double mass = 6.0e-3, gravity = 9.81, a = 5.996e-9, b = 4.85e-5;
  return ((gravity - acc) * mass - a / (d * d * d * d)) * d * d / b;
}

Samples make_samples() {
  Samples s;
  std::mt19937 noise_source(2);
  std::normal_distribution<double> noise(0.0, std::sqrt(1.2e-7));
  const double w = std::numbers::pi;  // rad/s
  const auto gap = [w](double t) { return 0.026 + 0.002 * std::sin(w * t); };
  const auto current = [&](double t) { return current_for(gap(t), -0.002 * w * w * std::sin(w * t)); };
  for (int k = 0; k < kSamples; ++k) {
    const double t = k / kRateHz;
    const double h = 1e-6;
    const double di_dt = (current(t + h) - current(t - h)) / (2.0 * h);
    s.gap.push_back(gap(t));
    s.voltage.push_back((di_dt + 165.6 * current(t)) / 61.61);  // eq. 32 solved for v
    s.measured_gap.push_back(gap(t) + noise(noise_source));
  }
  return s;
}

const Samples& samples() {
  static const Samples s = make_samples();
  return s;
}

/// One estimator block fed as the pipeline feeds it (measurement: direct.gap, input: stage.truth).
struct Rig {
  explicit Rig(const std::string& plugin, const std::string& own_params)
      : host(plugin, kCommon + own_params, kRateHz, kModels) {
    host.feed("measurement", {{"gap", "m"}});
    host.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start %s:\n%s", plugin.c_str(), host.diagnostics().c_str());
      std::exit(1);
    }
    measurement = host.input("measurement").data();
    input = host.input("input").data();
    state_out = host.output("state").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const Samples& s = samples();
    // The input carries what was held over the period that just ended.
    const int held = next == 0 ? kSamples - 1 : next - 1;
    measurement[0] = s.measured_gap[static_cast<std::size_t>(next)];
    input[0] = s.gap[static_cast<std::size_t>(held)];
    input[1] = s.voltage[static_cast<std::size_t>(held)];
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: the estimator faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  double* measurement = nullptr;
  double* input = nullptr;
  const double* state_out = nullptr;
  int next = 0;
};

void run(benchmark::State& state, Rig& rig) {
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.state_out[0]);
  }
}

// After: the algebra sized at compile time for n = 3, m = 1 (compile_time_sizes: true, the
// default). Before: the generic algebra every other size runs (compile_time_sizes: false),
// which gives the same bits.
void BM_UkfCycle(benchmark::State& state) {
  static Rig rig("estimator.ukf", "alpha: 0.002\nbeta: 2\nkappa: 0\n");
  run(state, rig);
}
BENCHMARK(BM_UkfCycle);

void BM_UkfCycleGeneric(benchmark::State& state) {
  static Rig rig("estimator.ukf", "alpha: 0.002\nbeta: 2\nkappa: 0\ncompile_time_sizes: false\n");
  run(state, rig);
}
BENCHMARK(BM_UkfCycleGeneric);

void BM_EkfCycle(benchmark::State& state) {
  static Rig rig("estimator.ekf", "");
  run(state, rig);
}
BENCHMARK(BM_EkfCycle);

void BM_EkfCycleGeneric(benchmark::State& state) {
  static Rig rig("estimator.ekf", "compile_time_sizes: false\n");
  run(state, rig);
}
BENCHMARK(BM_EkfCycleGeneric);

/// estimator.kalman as config/kawato_planar.yaml runs it: three constant-acceleration axes
/// (x, y, theta_z) at 800 Hz, R from `r` (the covariance input left unconnected). The poses: a
/// 1 Hz circle of 100 um and a 1 mrad swing, measured with the configured noise (fixed seed),
/// 4000 samples replayed in a loop after 2000 cycles of warm-up. Fixed sizes already (3 states
/// per axis): one benchmark, the baseline for work on this filter.
struct KalmanRig {
  KalmanRig()
      : host("estimator.kalman",
             "motion: constant_acceleration\nq: [1.0e2, 1.0e2, 1.0e5]\np0: 1.0e-8\nr: [2.2e-10, 2.2e-10, 9.6e-9]\n",
             800.0) {
    host.feed("measurement", {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}});
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start estimator.kalman:\n%s", host.diagnostics().c_str());
      std::exit(1);
    }
    std::mt19937 noise_source(4);
    std::normal_distribution<double> position_noise(0.0, std::sqrt(2.2e-10));
    std::normal_distribution<double> angle_noise(0.0, std::sqrt(9.6e-9));
    for (int k = 0; k < kSamples; ++k) {
      const double phase = 2.0 * std::numbers::pi * k / 800.0;
      poses.push_back({100e-6 * std::cos(phase) + position_noise(noise_source),
                       100e-6 * std::sin(phase) + position_noise(noise_source),
                       1e-3 * std::sin(phase) + angle_noise(noise_source)});
    }
    measurement = host.input("measurement").data();
    pose_out = host.output("pose").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const std::array<double, 3>& pose = poses[static_cast<std::size_t>(next)];
    for (std::size_t i = 0; i < 3; ++i) measurement[i] = pose[i];
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: estimator.kalman faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  std::vector<std::array<double, 3>> poses;
  double* measurement = nullptr;
  const double* pose_out = nullptr;
  int next = 0;
};

void BM_KalmanCycle(benchmark::State& state) {
  static KalmanRig rig;
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.pose_out[0]);
  }
}
BENCHMARK(BM_KalmanCycle);

// ---------------------------------------------------------------------------------------
// GLSDC, encoder EKF, hybrid H2/H-inf and NPO, each on its shipped config's model and settings.
// After: compile_time_sizes: true (the default); before (…Generic): compile_time_sizes: false.

/// estimator.glsdc as config/kawato_planar.yaml runs it: the hall_fit model (harmonics 1 and 5,
/// sensors A and B), 3dof, one Gauss-Newton step per tick, 0.2 back-off, 1 mV noise, 800 Hz.
/// The samples come from io.sim with that config's board (1 mV noise, 16-bit ADC, seed 1) and
/// platen, driven open loop along x = 100 um (cos 2 pi t - 1), y = 100 um (cos 2.6 pi t - 1),
/// theta_z = 1 mrad (cos 2 pi t - 1): 4000 samples replayed in a loop after 2000 cycles of
/// warm-up.
const char* const kKawatoModels =
    "platen: {plugin: plant.planar_stage, mass_kg: 6.20, inertia_kg_m2: 0.054}\n"
    "hall_fit: {plugin: sensor.halbach_hall, pitch_m: 0.0508, gap_m: 0.002, harmonics: [1, 5],"
    " sensitivity_v_per_t: 8.43, sensors: [{name: A, x_m: 0.00635, y_m: 0.09525, channels: [a1, b1]},"
    " {name: B, x_m: -0.00635, y_m: -0.09525, channels: [c1, d2]}]}\n";

std::vector<std::array<double, 4>> kawato_hall_samples() {
  lode::BlockHost board("io.sim",
                        "plant: platen\nsensors: [hall_fit]\nnoise_std_v: 1.0e-3\nadc_bits: 16\nadc_range_v: 10\nseed: 1\n",
                        800.0, kKawatoModels);
  board.feed("command", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});
  if (!board.configure() || !board.activate()) {
    std::fprintf(stderr, "estimator_bench: cannot start io.sim:\n%s", board.diagnostics().c_str());
    std::exit(1);
  }
  std::vector<std::array<double, 4>> out;
  const double w = 2.0 * std::numbers::pi;
  for (int k = 0; k < kSamples; ++k) {
    if (board.step() != lode::StepStatus::ok) std::exit(1);
    const std::span<const double> signals = board.output("signals");
    out.push_back({signals[0], signals[1], signals[2], signals[3]});
    // The accelerations of the cosine paths (x'' = -A w^2 cos wt), times mass or inertia.
    const double t = k / 800.0;
    const std::span<double> command = board.input("command");
    command[0] = -6.20 * 1e-4 * w * w * std::cos(w * t);
    command[1] = -6.20 * 1e-4 * 1.69 * w * w * std::cos(1.3 * w * t);
    command[2] = -0.054 * 1e-3 * w * w * std::cos(w * t);
    if (board.write() != lode::StepStatus::ok) std::exit(1);
  }
  return out;
}

struct GlsdcRig {
  explicit GlsdcRig(const std::string& own_params)
      : host("estimator.glsdc",
             "model: hall_fit\nmode: 3dof\niterations: 1\nbackoff: 0.2\nnoise_std_v: 1.0e-3\n" + own_params, 800.0,
             kKawatoModels),
        signals(kawato_hall_samples()) {
    host.feed("measurement", {{"a1", "V"}, {"b1", "V"}, {"c1", "V"}, {"d2", "V"}});
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start estimator.glsdc:\n%s", host.diagnostics().c_str());
      std::exit(1);
    }
    measurement = host.input("measurement").data();
    pose_out = host.output("pose").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const std::array<double, 4>& y = signals[static_cast<std::size_t>(next)];
    for (std::size_t i = 0; i < 4; ++i) measurement[i] = y[i];
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: estimator.glsdc faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  std::vector<std::array<double, 4>> signals;
  double* measurement = nullptr;
  const double* pose_out = nullptr;
  int next = 0;
};

void BM_GlsdcCycle(benchmark::State& state) {
  static GlsdcRig rig("");
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.pose_out[0]);
  }
}
BENCHMARK(BM_GlsdcCycle);

void BM_GlsdcCycleGeneric(benchmark::State& state) {
  static GlsdcRig rig("compile_time_sizes: false\n");
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.pose_out[0]);
  }
}
BENCHMARK(BM_GlsdcCycleGeneric);

/// estimator.ekf_encoder as config/encoder_ekf.yaml runs it: the 4 um sin/cos head (1 V),
/// Singer model alpha = 200 pi, sigma_m^2 = 1e-5, R = diag(8 mV^2, 8 mV^2), 20 kHz. The samples:
/// io.sim with that config's stage (1 um, 5 Hz sine; 8 mV noise, 12-bit ADC, seed 1): 4000
/// samples (0.2 s, one full period) replayed in a loop after 2000 cycles of warm-up.
const char* const kEncoderModels =
    "axis: {plugin: plant.encoder_stage, amplitude_m: 1.0e-6, frequency_hz: 5.0}\n"
    "head: {plugin: sensor.sincos_encoder, pitch_m: 4.0e-6, amplitude_v: 1.0}\n";

struct EncoderEkfRig {
  explicit EncoderEkfRig(const std::string& own_params)
      : host("estimator.ekf_encoder",
             "model: head\nacceleration_pole_rad_s: 628.3185307179586\nacceleration_variance_m2_s4: 1.0e-5\n"
             "noise_std_v: 8.0e-3\ninitial_position_std_m: 4.0e-8\ninitial_velocity_std_m_s: 1.0e-4\n"
             "initial_acceleration_std_m_s2: 1.0e-2\n" + own_params,
             20000.0, kEncoderModels) {
    lode::BlockHost board("io.sim",
                          "plant: axis\nsensors: [head]\nnoise_std_v: 8.0e-3\nadc_bits: 12\nadc_range_v: 1.25\nseed: 1\n",
                          20000.0, kEncoderModels);
    if (!board.configure() || !board.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start io.sim:\n%s", board.diagnostics().c_str());
      std::exit(1);
    }
    for (int k = 0; k < kSamples; ++k) {
      if (board.step() != lode::StepStatus::ok || board.write() != lode::StepStatus::ok) std::exit(1);
      const std::span<const double> y = board.output("signals");
      signals.push_back({y[0], y[1]});
    }
    host.feed("signals", {{"sin", "V"}, {"cos", "V"}});
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start estimator.ekf_encoder:\n%s", host.diagnostics().c_str());
      std::exit(1);
    }
    input = host.input("signals").data();
    estimate_out = host.output("estimate").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const std::array<double, 2>& y = signals[static_cast<std::size_t>(next)];
    input[0] = y[0];
    input[1] = y[1];
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: estimator.ekf_encoder faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  std::vector<std::array<double, 2>> signals;
  double* input = nullptr;
  const double* estimate_out = nullptr;
  int next = 0;
};

void BM_EncoderEkfCycle(benchmark::State& state) {
  static EncoderEkfRig rig("");
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.estimate_out[0]);
  }
}
BENCHMARK(BM_EncoderEkfCycle);

void BM_EncoderEkfCycleGeneric(benchmark::State& state) {
  static EncoderEkfRig rig("compile_time_sizes: false\n");
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.estimate_out[0]);
  }
}
BENCHMARK(BM_EncoderEkfCycleGeneric);

/// Six pose-like axes measured with noise of the given std: x, y, z along 1 Hz paths of
/// 20 um, 10 um and 5 um, the angles 10 urad (fixed seed), 4000 samples at `rate_hz`.
std::vector<std::array<double, 6>> six_axis_poses(double rate_hz, double noise_std, unsigned seed) {
  std::mt19937 noise_source(seed);
  std::normal_distribution<double> noise(0.0, noise_std);
  std::vector<std::array<double, 6>> poses;
  for (int k = 0; k < kSamples; ++k) {
    const double phase = 2.0 * std::numbers::pi * k / rate_hz;
    const std::array<double, 6> truth = {20e-6 * std::cos(phase), 10e-6 * std::sin(phase), 5e-6 * std::sin(2 * phase),
                                         10e-6 * std::sin(phase),  10e-6 * std::cos(phase), 10e-6 * std::sin(3 * phase)};
    std::array<double, 6> measured{};
    for (std::size_t i = 0; i < 6; ++i) measured[i] = truth[i] + noise(noise_source);
    poses.push_back(measured);
  }
  return poses;
}

const lode::Elements kSixAxisPose = {{"x", "m"},     {"y", "m"},       {"theta_z", "rad"},
                                      {"z", "m"},     {"theta_x", "rad"}, {"theta_y", "rad"}};

/// estimator.hybrid_h2hinf as config/maglev6_hybrid.yaml runs it: six constant-acceleration
/// axes at 800 Hz with steady blended gains (d = 1, its q, r, theta and S), fed six noisy poses
/// (1 um noise). Its per-axis algebra is fixed-size 3 x 3 already (there is no generic path):
/// one benchmark, the baseline for work on this filter.
struct HybridRig {
  HybridRig()
      : host("estimator.hybrid_h2hinf",
             "d: 1.0\nq: [1.0e3, 1.0e3, 1.0e5, 1.0e9, 1.0e9, 1.0e9]\nr: 1.0e-6\n"
             "hinf_theta: [8.0e5, 8.0e5, 8.0e5, 5.0e5, 5.0e5, 5.0e5]\nhinf_error_weight: [1, 0, 0]\noutput: filtered\n",
             800.0),
        poses(six_axis_poses(800.0, 1e-6, 5)) {
    host.feed("measurement", kSixAxisPose);
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start estimator.hybrid_h2hinf:\n%s", host.diagnostics().c_str());
      std::exit(1);
    }
    measurement = host.input("measurement").data();
    pose_out = host.output("pose").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const std::array<double, 6>& pose = poses[static_cast<std::size_t>(next)];
    for (std::size_t i = 0; i < 6; ++i) measurement[i] = pose[i];
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: estimator.hybrid_h2hinf faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  std::vector<std::array<double, 6>> poses;
  double* measurement = nullptr;
  const double* pose_out = nullptr;
  int next = 0;
};

void BM_HybridCycle(benchmark::State& state) {
  static HybridRig rig;
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.pose_out[0]);
  }
}
BENCHMARK(BM_HybridCycle);

/// estimator.npo as config/npo_velocity.yaml runs it: the plant.rigid_body6 stage of Table 1 as
/// the process model (nonlinear dynamics, one RK4 step per period), d0 = 100, a0 = 1e4 1/s,
/// exact integrator, 2500 Hz; six noisy poses (10 nm / 10 nrad noise) and a small held wrench.
/// Its 12-state algebra is fixed-size already (there is no generic path): one benchmark.
struct NpoRig {
  NpoRig()
      : host("estimator.npo", "model: stage\nd0: 100.0\na0_per_s: 1.0e4\nintegrator: exact\ndynamics: nonlinear\n",
             2500.0,
             "stage: {plugin: plant.rigid_body6, mass_kg: 0.931, inertia_kg_m2: [1.799e-3, 1.834e-3, 3.336e-3],"
             " gravity_m_s2: 0.0}\n"),
        poses(six_axis_poses(2500.0, 1e-8, 6)) {
    host.feed("measurement", {{"x", "m"}, {"y", "m"}, {"z", "m"}, {"phi", "rad"}, {"theta", "rad"}, {"psi", "rad"}});
    host.feed("force", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}});
    if (!host.configure() || !host.activate()) {
      std::fprintf(stderr, "estimator_bench: cannot start estimator.npo:\n%s", host.diagnostics().c_str());
      std::exit(1);
    }
    measurement = host.input("measurement").data();
    force = host.input("force").data();
    velocity_out = host.output("velocity").data();
    for (int k = 0; k < kWarmUp; ++k) cycle();
  }
  void cycle() {
    const std::array<double, 6>& pose = poses[static_cast<std::size_t>(next)];
    for (std::size_t i = 0; i < 6; ++i) {
      measurement[i] = pose[i];
      force[i] = 1e-3 * pose[(i + 1) % 6] / 20e-6;  // a few mN / uN*m, varying with the path
    }
    if (host.step() != lode::StepStatus::ok) {
      std::fprintf(stderr, "estimator_bench: estimator.npo faulted: %s\n", host.block().fault_reason());
      std::exit(1);
    }
    next = next + 1 == kSamples ? 0 : next + 1;
  }
  lode::BlockHost host;
  std::vector<std::array<double, 6>> poses;
  double* measurement = nullptr;
  double* force = nullptr;
  const double* velocity_out = nullptr;
  int next = 0;
};

void BM_NpoCycle(benchmark::State& state) {
  static NpoRig rig;
  for (auto _ : state) {
    rig.cycle();
    benchmark::DoNotOptimize(rig.velocity_out[0]);
  }
}
BENCHMARK(BM_NpoCycle);

}  // namespace

BENCHMARK_MAIN();
