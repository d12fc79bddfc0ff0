#include "sincos_encoder.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

SincosEncoder::SincosEncoder() {
  const Status applied = apply(SincosEncoderConfig{});
  (void)applied;  // the defaults are valid (Table 1)
}

Status SincosEncoder::configure(Params& params) {
  const SincosEncoderConfig defaults;
  SincosEncoderConfig c;
  c.pitch_m = params.number("pitch_m");
  c.amplitude_v = params.number("amplitude_v", defaults.amplitude_v);
  const std::vector<std::string> names = params.texts("channels", {"sin", "cos"});
  if (names.size() == 2) {
    c.channel_names = {names[0], names[1]};
  } else {
    params.fail("channels", "expected two names [sine channel, cosine channel], got " +
                                std::to_string(names.size()));
  }
  const std::vector<double> offsets = params.numbers("offset_v", std::vector<double>{0.0, 0.0}, 2);
  if (offsets.size() == 2) c.offset_v = {offsets[0], offsets[1]};
  c.amplitude_ratio = params.number("amplitude_ratio", defaults.amplitude_ratio);
  c.quadrature_error_rad = params.number("quadrature_error_rad", defaults.quadrature_error_rad);

  // Every check at its own key, so one run reports every problem.
  params.check(std::isfinite(c.pitch_m) && c.pitch_m > 0.0, "pitch_m",
               "the scale period must be > 0 m (Table 1: 4e-6), got " + number_text(c.pitch_m));
  params.check(std::isfinite(c.amplitude_v) && c.amplitude_v > 0.0, "amplitude_v",
               "the signal amplitude V must be > 0 V (Table 1: 1 V), got " + number_text(c.amplitude_v));
  params.check(std::isfinite(c.amplitude_ratio) && c.amplitude_ratio > 0.0, "amplitude_ratio",
               "the cos/sin amplitude ratio must be > 0 (ideal: 1), got " + number_text(c.amplitude_ratio));
  params.check(std::isfinite(c.quadrature_error_rad) && std::abs(c.quadrature_error_rad) < 0.5 * std::numbers::pi,
               "quadrature_error_rad",
               "the phase error must be within +-pi/2 rad (ideal: 0), got " + number_text(c.quadrature_error_rad));
  params.check(std::isfinite(c.offset_v[0]) && std::isfinite(c.offset_v[1]), "offset_v",
               "offsets must be finite");
  params.check(c.channel_names[0] != c.channel_names[1] && !c.channel_names[0].empty() &&
                   !c.channel_names[1].empty(),
               "channels", "the two channel names must be different and non-empty");
  if (!params.ok()) return Status::error("invalid parameters");
  return apply(c);
}

Status SincosEncoder::apply(const SincosEncoderConfig& config) {
  if (!(config.pitch_m > 0.0) || !(config.amplitude_v > 0.0) || !(config.amplitude_ratio > 0.0)) {
    return Status::error("sensor.sincos_encoder: pitch_m, amplitude_v and amplitude_ratio must be > 0");
  }
  config_ = config;
  wavenumber_rad_per_m_ = 2.0 * std::numbers::pi / config_.pitch_m;
  cos_amplitude_v_ = config_.amplitude_ratio * config_.amplitude_v;
  declare_measurement_elements({{"x", "m"}}, {{config_.channel_names[0], "V"}, {config_.channel_names[1], "V"}});
  return Status::ok();
}

double SincosEncoder::phase_rad(double position_m) const noexcept {
  const double cycles = position_m / config_.pitch_m;
  return 2.0 * std::numbers::pi * (cycles - std::nearbyint(cycles));
}

void SincosEncoder::evaluate(const double* state, double* y) const noexcept {
  const double theta = phase_rad(state[0]);
  // eq. 4 (plus the optional offsets, amplitude ratio and quadrature error).
  y[kSin] = config_.amplitude_v * std::sin(theta) + config_.offset_v[0];
  y[kCos] = cos_amplitude_v_ * std::cos(theta + config_.quadrature_error_rad) + config_.offset_v[1];
}

void SincosEncoder::jacobian(const double* state, double* y, double* H) const noexcept {
  const double theta = phase_rad(state[0]);
  const double s = std::sin(theta);
  const double c = std::cos(theta);
  const double c_shifted = std::cos(theta + config_.quadrature_error_rad);
  const double s_shifted = std::sin(theta + config_.quadrature_error_rad);
  y[kSin] = config_.amplitude_v * s + config_.offset_v[0];
  y[kCos] = cos_amplitude_v_ * c_shifted + config_.offset_v[1];
  // Corrected eq. 11: the trig arguments are 2 pi f_s x (printed: x), one column (x).
  H[kSin] = wavenumber_rad_per_m_ * config_.amplitude_v * c;
  H[kCos] = -wavenumber_rad_per_m_ * cos_amplitude_v_ * s_shifted;
}

void SincosEncoder::describe(Json& out) const {
  out["pitch_m"] = config_.pitch_m;
  out["spatial_frequency_1_per_m"] = 1.0 / config_.pitch_m;  // f_s of eq. 1
  out["wavenumber_rad_per_m"] = wavenumber_rad_per_m_;
  out["amplitude_v"] = config_.amplitude_v;
  // |dh/dx| = 2 pi f_s V: volts per metre at the steepest point of each channel; with
  // noise sigma per channel the single-sample position noise is sigma / (2 pi f_s V).
  out["slope_v_per_m"] = wavenumber_rad_per_m_ * config_.amplitude_v;
  Json names = Json::array();
  names.push(config_.channel_names[0]);
  names.push(config_.channel_names[1]);
  out["channels"] = std::move(names);
  const bool ideal = config_.offset_v[0] == 0.0 && config_.offset_v[1] == 0.0 &&
                     config_.amplitude_ratio == 1.0 && config_.quadrature_error_rad == 0.0;
  out["ideal"] = ideal;  // true: exactly the paper's eq. 1/4
  out["offset_v"] = std::vector<double>{config_.offset_v[0], config_.offset_v[1]};
  out["amplitude_ratio"] = config_.amplitude_ratio;
  out["quadrature_error_rad"] = config_.quadrature_error_rad;
  out["equation"] = ideal ? "h(x) = [V sin(2 pi x / pitch); V cos(2 pi x / pitch)] (eq. 4)"
                          : "h(x) = [V sin(th) + o_sin; r V cos(th + phi) + o_cos], th = 2 pi x / pitch";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"pitch_m", "number", nullptr, "scale period = 1/f_s, > 0 (Table 1: 4e-6; experiment: 20e-6)"},
    {"amplitude_v", "number", "1.0", "signal amplitude V of eq. 1 [V], > 0"},
    {"channels", "list<text>[2]", "[sin, cos]", "names of the sine and cosine channels"},
    {"offset_v", "list<number>[2]", "[0, 0]", "DC offsets of sin and cos [V] (extension, not in the paper)"},
    {"amplitude_ratio", "number", "1", "cos amplitude / sin amplitude (extension, not in the paper)"},
    {"quadrature_error_rad", "number", "0", "phase error of the cos channel [rad] (extension, not in the paper)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::SincosEncoder, "sensor.sincos_encoder", lode::PluginKind::sensor, "0.1.0",
            "Analog sin/cos linear encoder (Zimmerman 2006 eq. 1, 4) with the corrected eq. 11 Jacobian",
            lode::plugins::kParams, lode::kNoPorts)
