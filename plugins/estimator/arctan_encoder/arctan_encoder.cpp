#include "arctan_encoder.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace arctan_encoder {

bool decode_angle(Method method, double z_sin, double z_cos, double& theta_rad) noexcept {
  if (!std::isfinite(z_sin) || !std::isfinite(z_cos)) return false;
  const double norm = std::hypot(z_sin, z_cos);
  if (!(norm > 0.0)) return false;
  if (method == Method::atan2) {
    theta_rad = std::atan2(z_sin, z_cos);  // eq. 2
    return true;
  }
  // eq. 3: use the better-conditioned inverse function of the normalised signals (the one
  // whose argument is away from +-1), then place the angle in its quadrant from the signs,
  // which the printed equation leaves out.
  constexpr double kPi = std::numbers::pi;
  if (std::abs(z_sin) <= std::abs(z_cos)) {
    const double principal = std::asin(z_sin / norm);  // [-pi/4, pi/4]
    theta_rad = z_cos >= 0.0 ? principal : (principal >= 0.0 ? kPi - principal : -kPi - principal);
  } else {
    const double principal = std::acos(z_cos / norm);  // (pi/4, 3 pi/4)
    theta_rad = z_sin >= 0.0 ? principal : -principal;
  }
  if (theta_rad <= -kPi) theta_rad += 2.0 * kPi;  // (-pi, pi], as atan2
  return true;
}

void Decoder::configure(double pitch_m, double period_s, double initial_position_m) noexcept {
  pitch_m_ = pitch_m;
  period_s_ = period_s;
  initial_position_m_ = initial_position_m;
  reset();
}

void Decoder::reset() noexcept {
  first_ = true;
  previous_theta_rad_ = 0.0;
  cycle_count_ = 0;
  position_m_ = initial_position_m_;
  velocity_m_s_ = 0.0;
}

void Decoder::update(double theta_rad) noexcept {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  const double fraction = theta_rad / kTwoPi;  // (-1/2, 1/2]
  if (first_) {
    // The whole number of periods that puts the first position nearest the reference.
    cycle_count_ = static_cast<std::int64_t>(std::llround(initial_position_m_ / pitch_m_ - fraction));
    position_m_ = (static_cast<double>(cycle_count_) + fraction) * pitch_m_;
    velocity_m_s_ = 0.0;
    previous_theta_rad_ = theta_rad;
    first_ = false;
    return;
  }
  // Coarse position: a jump of more than half a period between samples is a wrap of the
  // fine angle, not motion (valid while |v| T < pitch / 2).
  const double jump = theta_rad - previous_theta_rad_;
  if (jump > std::numbers::pi) {
    --cycle_count_;
  } else if (jump < -std::numbers::pi) {
    ++cycle_count_;
  }
  previous_theta_rad_ = theta_rad;
  const double position_m = (static_cast<double>(cycle_count_) + fraction) * pitch_m_;
  velocity_m_s_ = (position_m - position_m_) / period_s_;  // backward difference
  position_m_ = position_m;
}

}  // namespace arctan_encoder

namespace {

}  // namespace

Status ArctanEncoder::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();
  pitch_m_ = params.number("pitch_m");
  const std::string method = params.choice("method", {"atan2", "arcsin_arccos"}, std::string_view("atan2"));
  method_ = method == "arcsin_arccos" ? arctan_encoder::Method::arcsin_arccos : arctan_encoder::Method::atan2;
  initial_position_m_ = params.number("initial_position_m", 0.0);

  params.check(std::isfinite(pitch_m_) && pitch_m_ > 0.0, "pitch_m",
               "the scale period must be > 0 m (Table 1: 4e-6), got " + number_text(pitch_m_));
  params.check(std::isfinite(initial_position_m_), "initial_position_m",
               "must be finite, got " + number_text(initial_position_m_));

  ctx.declare_input(signals_, "signals", {{"sin", "V"}, {"cos", "V"}});
  ctx.declare_output(estimate_, "estimate", {{"x", "m"}, {"v", "m/s"}});
  ctx.declare_output(cycle_count_, "cycle_count", {{"count", "1"}});

  if (!params.ok()) return Status::error("invalid parameters");
  decoder_.configure(pitch_m_, period_s_, initial_position_m_);
  return Status::ok();
}

Status ArctanEncoder::activate() {
  decoder_.reset();
  estimate_[0] = initial_position_m_;
  estimate_[1] = 0.0;
  cycle_count_[0] = 0.0;
  return Status::ok();
}

StepStatus ArctanEncoder::step(const Tick& /*tick*/) noexcept {
  double theta_rad = 0.0;
  if (!arctan_encoder::decode_angle(method_, signals_[0], signals_[1], theta_rad)) {
    return fault("sin/cos sample is zero or not finite: no angle");
  }
  decoder_.update(theta_rad);
  estimate_[0] = decoder_.position_m();
  estimate_[1] = decoder_.velocity_m_s();
  cycle_count_[0] = static_cast<double>(decoder_.cycle_count());
  return StepStatus::ok;
}

void ArctanEncoder::describe(Json& out) const {
  out["method"] = method_ == arctan_encoder::Method::atan2 ? "atan2 (eq. 2)"
                                                          : "arcsin/arccos with quadrant logic (eq. 3)";
  out["pitch_m"] = pitch_m_;
  out["period_s"] = period_s_;
  out["initial_position_m"] = initial_position_m_;
  out["position"] = "x_k = (n_k + theta_k / (2 pi)) pitch, n_k counts wraps of theta";
  out["velocity"] = "backward difference (x_k - x_{k-1}) / T";
  // Counting is unambiguous while the head moves less than half a period per sample.
  out["max_unambiguous_speed_m_s"] = 0.5 * pitch_m_ / period_s_;
  // A position noise sigma_x per sample becomes sqrt(2) sigma_x / T in the velocity.
  out["velocity_noise_gain_1_per_s"] = std::numbers::sqrt2 / period_s_;
}

namespace {

constexpr ParamDoc kParams[] = {
    {"pitch_m", "number", nullptr, "scale period [m], > 0 (Table 1: 4e-6); must equal the encoder's"},
    {"method", "text", "atan2", "atan2 (eq. 2) or arcsin_arccos (eq. 3 with quadrant logic)"},
    {"initial_position_m", "number", "0",
     "homing reference: the first sample's cycle count puts the position nearest this value [m]"},
};

constexpr PortSpec kPorts[] = {
    {"signals", PortDirection::in, "sin [V], cos [V] encoder channels (e.g. io.sim signals)"},
    {"estimate", PortDirection::out, "x [m] absolute position (cycle count + fine angle), v [m/s] backward difference"},
    {"cycle_count", PortDirection::out, "count [1]: the coarse period counter"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::ArctanEncoder, "estimator.arctan_encoder", lode::PluginKind::estimator, "0.1.0",
            "Baseline sin/cos decoder: atan2 or arcsin/arccos + cycle counter, backward-difference velocity "
            "(Zimmerman 2006 eq. 2-3)",
            lode::plugins::kParams, lode::plugins::kPorts)
