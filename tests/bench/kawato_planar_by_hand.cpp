#include "kawato_planar_by_hand.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace lode::bench {

namespace {

// config/kawato_planar.yaml, written out.
constexpr std::int64_t kPeriodNs = 1'250'000;
constexpr double kNoiseStdV = 1.0e-3;
constexpr int kAdcBits = 16;
constexpr double kAdcRangeV = 10.0;
constexpr std::uint64_t kSeed = 1;
constexpr std::array<double, 3> kQ{1.0e2, 1.0e2, 1.0e5};
constexpr double kP0 = 1.0e-8;
constexpr std::array<std::int64_t, 2> kStepTimesNs{1'000'000'000, 2'000'000'000};
constexpr std::array<std::array<double, 3>, 3> kStepValues{{{0.0, 0.0, 0.0},  // before the first step
                                                             {100.0e-6, 0.0, 0.0},
                                                             {100.0e-6, 0.0, 1.0e-3}}};
constexpr std::array<double, 3> kControllerGain{4.09e5, 4.09e5, 7.6e3};

plugins::HalbachHallConfig hall_config() {
  plugins::HalbachHallConfig c;
  c.pitch_m = 0.0508;
  c.gap_m = 0.002;
  c.harmonics = {1, 5};
  c.sensitivity_v_per_t = 8.43;
  plugins::HalbachSensorConfig a;
  a.name = "A";
  a.x_m = 0.00635;
  a.y_m = 0.09525;
  a.channels = {"a1", "b1"};
  plugins::HalbachSensorConfig b;
  b.name = "B";
  b.x_m = -0.00635;
  b.y_m = -0.09525;
  b.channels = {"c1", "d2"};
  c.sensors = {a, b};
  return c;
}

}  // namespace

KawatoPlanarByHand::KawatoPlanarByHand(Pipeline& lender) {
  plugins::PlanarStageConfig stage;
  stage.mass_kg = 6.20;
  stage.inertia_kg_m2 = 0.054;
  plant_.apply(stage);
  if (Status s = field_.apply(hall_config()); !s) {
    error_ = "hall_true: " + s.message();
    return;
  }
  noise_.seed(kSeed);
  converter_ = plugins::sim::ConverterScale::of(kAdcBits, kAdcRangeV);

  // The plugin module built the instance; this program has the same class compiled in.
  if (lender.plugin_of("glsdc") == "estimator.glsdc") glsdc_ = static_cast<plugins::Glsdc*>(lender.block("glsdc"));
  const auto signals = lender.signal("stage.signals");
  const auto pose = lender.signal("glsdc.pose");
  const auto covariance = lender.signal("glsdc.covariance");
  const auto cost = lender.signal("glsdc.cost");
  if (glsdc_ == nullptr || !signals || !pose || !covariance || !cost || signals->size() != kChannels) {
    error_ = "the lending pipeline is not kawato_planar (no estimator.glsdc 'glsdc' on 4 channels)";
    return;
  }
  // The GLSDC's input is this storage; writing it is what the simulated board does.
  signals_ = const_cast<double*>(signals->data);
  glsdc_pose_ = pose->data;
  glsdc_covariance_ = covariance->data;

  const double period_s = 1.0 / kRateHz;
  for (std::size_t i = 0; i < kAxes; ++i) {
    filters_[i].configure(plugins::kalman::AxisModel<3>::make(period_s, kQ[i]), kP0);
    start_at_measurement_[i] = true;
    const auto design = plugins::discrete_tf::matched_pole_zero({-8.31, -10.0}, {0.0, -1134.0},
                                                                kControllerGain[i], period_s);
    if (!design) {
      error_ = "ctrl: " + design.error();
      return;
    }
    controllers_[i].configure(*design, 0.0);
    controllers_[i].reset();
  }

  outputs_ = {{"stage.signals", {signals_, kChannels}},
              {"stage.counts", {counts_.data(), kChannels}},
              {"stage.truth", {truth_.data(), truth_.size()}},
              {"stage.plant_state", {plant_state_.data(), plant_state_.size()}},
              {"glsdc.pose", {glsdc_pose_, 3}},
              {"glsdc.covariance", {glsdc_covariance_, 9}},
              {"glsdc.cost", {cost->data, 1}},
              {"kf.pose", {kf_pose_.data(), kAxes}},
              {"kf.velocity", {kf_velocity_.data(), kAxes}},
              {"kf.acceleration", {kf_acceleration_.data(), kAxes}},
              {"kf.innovation", {kf_innovation_.data(), kAxes}},
              {"ref.out", {reference_.data(), kAxes}},
              {"ctrl.out", {command_.data(), kAxes}}};
}

bool KawatoPlanarByHand::cycle(std::uint64_t cycle) noexcept {
  const std::int64_t time_ns = static_cast<std::int64_t>(cycle) * kPeriodNs;

  // stage, read phase: sample the platen, its field at the sensors, noise, converter.
  plant_.output(truth_.data());
  for (double v : truth_)
    if (!std::isfinite(v)) return false;
  plant_.state(plant_state_.data());
  field_.evaluate(truth_.data(), clean_.data());
  for (std::size_t c = 0; c < kChannels; ++c) {
    const double volts = clean_[c] + kNoiseStdV * noise_();
    if (!std::isfinite(volts)) return false;
    bool clipped = false;
    counts_[c] = converter_.code(volts, clipped);
    signals_[c] = counts_[c] * converter_.lsb_v;
  }

  // glsdc: one Gauss-Newton step on the four channels.
  Tick tick;
  tick.cycle = cycle;
  tick.time_ns = time_ns;
  tick.dt_s = 1.0 / kRateHz;
  if (glsdc_->step(tick) != StepStatus::ok) return false;

  // kf: three constant-acceleration filters, R(i,i) from the GLSDC's covariance.
  std::array<plugins::kalman::AxisFilter<3>::Cycle, kAxes> updates;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const double measurement = glsdc_pose_[i];
    const double r = glsdc_covariance_[i * kAxes + i];
    if (!std::isfinite(measurement) || !(r > 0.0) || !std::isfinite(r)) return false;
    if (!filters_[i].compute_update(measurement, r, start_at_measurement_[i], updates[i])) return false;
  }
  for (std::size_t i = 0; i < kAxes; ++i) {
    filters_[i].commit(updates[i]);
    start_at_measurement_[i] = false;
    const auto& x = filters_[i].predicted();
    kf_pose_[i] = x(0);
    kf_velocity_[i] = x(1);
    kf_acceleration_[i] = x(2);
    kf_innovation_[i] = filters_[i].innovation();
  }

  // ref: the steps whose time has come.
  const auto reached = static_cast<std::size_t>(
      std::upper_bound(kStepTimesNs.begin(), kStepTimesNs.end(), time_ns) - kStepTimesNs.begin());
  reference_ = kStepValues[reached];

  // ctrl: lead-lag per axis on reference - estimate.
  std::array<double, kAxes> error{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    error[i] = reference_[i] - kf_pose_[i];
    if (!std::isfinite(error[i])) return false;
  }
  for (std::size_t i = 0; i < kAxes; ++i)
    if (!controllers_[i].step(error[i], command_[i])) return false;

  // stage, write phase: the command held for one period moves the platen.
  for (double u : command_)
    if (!std::isfinite(u)) return false;
  plant_.advance(tick.dt_s, command_.data());
  return true;
}

}  // namespace lode::bench
