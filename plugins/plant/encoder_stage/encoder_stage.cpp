#include "encoder_stage.hpp"

#include <cmath>
#include <numbers>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

EncoderStage::EncoderStage() {
  declare_plant_elements({}, {{"x", "m"}, {"v", "m/s"}}, {{"x", "m"}, {"v", "m/s"}, {"a", "m/s^2"}});
  apply(EncoderStageConfig{});
}

Status EncoderStage::configure(Params& params) {
  EncoderStageConfig c;
  c.offset_m = params.number("offset_m", 0.0);
  c.velocity_m_s = params.number("velocity_m_s", 0.0);
  c.amplitude_m = params.number("amplitude_m", 0.0);
  c.frequency_hz = params.number("frequency_hz", 0.0);
  c.phase_rad = params.number("phase_rad", 0.0);

  params.check(std::isfinite(c.offset_m), "offset_m", "must be finite, got " + number_text(c.offset_m));
  params.check(std::isfinite(c.velocity_m_s), "velocity_m_s", "must be finite, got " + number_text(c.velocity_m_s));
  params.check(std::isfinite(c.amplitude_m) && c.amplitude_m >= 0.0, "amplitude_m",
               "must be >= 0 m (the phase sets the sign), got " + number_text(c.amplitude_m));
  params.check(std::isfinite(c.frequency_hz) && c.frequency_hz >= 0.0, "frequency_hz",
               "must be >= 0 Hz, got " + number_text(c.frequency_hz));
  params.check(std::isfinite(c.phase_rad), "phase_rad", "must be finite, got " + number_text(c.phase_rad));
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void EncoderStage::apply(const EncoderStageConfig& config) {
  config_ = config;
  reset();
}

std::array<double, EncoderStage::kStateSize> EncoderStage::trajectory(double t_s) const noexcept {
  // Whole cycles are removed before the sine (f t can reach 1e3 in a long run), so the
  // argument stays within one period and keeps full precision.
  const double cycles = config_.frequency_hz * t_s;
  const double angle = 2.0 * std::numbers::pi * (cycles - std::floor(cycles)) + config_.phase_rad;
  const double omega = 2.0 * std::numbers::pi * config_.frequency_hz;
  const double s = std::sin(angle);
  const double c = std::cos(angle);
  return {config_.offset_m + config_.velocity_m_s * t_s + config_.amplitude_m * s,
          config_.velocity_m_s + omega * config_.amplitude_m * c,
          -omega * omega * config_.amplitude_m * s};
}

void EncoderStage::reset() noexcept {
  time_s_ = 0.0;
  time_compensation_s_ = 0.0;
  x_ = trajectory(0.0);
}

void EncoderStage::advance(double dt_s, const double* /*u*/) noexcept {
  // Kahan summation: 1e5 steps of 10 us would otherwise accumulate ~1e-11 s of rounding.
  const double step = dt_s - time_compensation_s_;
  const double next = time_s_ + step;
  time_compensation_s_ = (next - time_s_) - step;
  time_s_ = next;
  x_ = trajectory(time_s_);
}

void EncoderStage::output(double* y) const noexcept {
  y[0] = x_[kX];
  y[1] = x_[kV];
}

void EncoderStage::state(double* x) const noexcept {
  for (std::size_t i = 0; i < kStateSize; ++i) x[i] = x_[i];
}

void EncoderStage::describe(Json& out) const {
  out["trajectory"] = "x(t) = offset_m + velocity_m_s t + amplitude_m sin(2 pi frequency_hz t + phase_rad)";
  out["offset_m"] = config_.offset_m;
  out["velocity_m_s"] = config_.velocity_m_s;
  out["amplitude_m"] = config_.amplitude_m;
  out["frequency_hz"] = config_.frequency_hz;
  out["phase_rad"] = config_.phase_rad;
  const double omega = 2.0 * std::numbers::pi * config_.frequency_hz;
  // Peaks of the truth: what the filter's Singer model must cover (the authors' tuning advice)
  // and what the baseline's cycle counter must resolve (|v| T < pitch / 2).
  out["peak_velocity_m_s"] = std::abs(config_.velocity_m_s) + omega * config_.amplitude_m;
  out["peak_acceleration_m_s2"] = omega * omega * config_.amplitude_m;
  out["inputs"] = "none (prescribed motion, open-loop experiment of the paper's Fig. 2)";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"offset_m", "number", "0", "position at t = 0 without the sinusoid [m]"},
    {"velocity_m_s", "number", "0", "constant velocity [m/s] (the paper's ramp: 2e-3)"},
    {"amplitude_m", "number", "0", "sinusoid amplitude A [m], >= 0 (the paper: 0.1e-6 ... 2e-6)"},
    {"frequency_hz", "number", "0", "sinusoid frequency f [Hz], >= 0 (the paper: 2, 5, 10)"},
    {"phase_rad", "number", "0", "sinusoid phase at t = 0 [rad]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::EncoderStage, "plant.encoder_stage", lode::PluginKind::plant, "0.1.0",
            "Stage axis on a prescribed trajectory (offset + ramp + sinusoid), the signal generator of "
            "Zimmerman 2006 Fig. 2",
            lode::plugins::kParams, lode::kNoPorts)
