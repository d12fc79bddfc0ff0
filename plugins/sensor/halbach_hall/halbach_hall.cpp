#include "halbach_hall.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kMu0 = 4.0e-7 * kPi;  // vacuum permeability [T*m/A]; cancels in B = f(B_r)

/// Samples per pitch when searching the maximum model error (enough for harmonics < 100).
constexpr int kErrorSamplesPerPitch = 4096;

/// What the sensors see: the planar pose, before and after the sensors are known.
Elements planar_pose() { return {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}}; }

}  // namespace

// ---------------------------------------------------------------------------------------
// Physics of one 1-D Halbach array (Kawato 2005, eq. 3.2-3.14).

double HalbachHarmonic::amplitude_t() const { return std::hypot(sin_t, cos_t); }

HalbachHarmonic halbach_field_harmonic(int n, double pitch_m, double gap_m,
                                       double magnet_thickness_m, double br_strong_t,
                                       double weak_ratio) {
  using Complex = std::complex<double>;
  const Complex j(0.0, 1.0);
  // Per-array peak magnetisation: each strong magnet carries the vertical parts of both
  // orthogonal arrays, so one array sees half of it (README "Deviations" 2).
  const double m0 = br_strong_t / (2.0 * kMu0);
  // Square-wave Fourier coefficient of M_Z (eq. 3.5): + for n = 8m+1, 8m+3; - for 8m+5, 8m+7.
  const int n_mod_8 = n % 8;
  const double sign = (n_mod_8 == 1 || n_mod_8 == 3) ? 1.0 : -1.0;
  const double mz = sign * std::numbers::sqrt2 * m0 / (kPi * n);
  // j^n for odd n.
  const Complex j_pow_n = (n % 4 == 1) ? j : -j;
  // eq. 3.6 with its sign corrected (README "Deviations" 1): M_Xn = -j^n r M_Zn puts the strong
  // side (fundamental and 5th scaled by 1 + r) towards the sensors.
  const Complex mx = -j_pow_n * weak_ratio * mz;
  // eq. 3.10: decay with the gap, thickness factor of a finite magnet layer.
  const double gamma = 2.0 * kPi * n / pitch_m;
  const double decay = std::exp(-gamma * gap_m) * (1.0 - std::exp(-gamma * magnet_thickness_m));
  const Complex bx = 0.5 * kMu0 * (mx - j * mz) * decay;
  // eq. 3.14 read as "n >= 1, real part, x2": B_X(X) = 2 Re{B_Xn e^{-j n w X}}
  //   = 2 Re(B_Xn) cos(n w X) + 2 Im(B_Xn) sin(n w X).
  HalbachHarmonic h;
  h.n = n;
  h.sin_t = 2.0 * bx.imag();
  h.cos_t = 2.0 * bx.real();
  return h;
}

// ---------------------------------------------------------------------------------------
// Validation, shared by configure(Params&) (located errors) and apply() (tests).

bool validate_halbach_config(const HalbachHallConfig& c, const HalbachConfigReporter& report) {
  bool ok = true;
  auto fail = [&](HalbachConfigScope scope, std::size_t index, std::string_view key,
                  std::string message) {
    ok = false;
    report(scope, index, key, std::move(message));
  };
  auto top = [&](std::string_view key, std::string message) {
    fail(HalbachConfigScope::top, 0, key, std::move(message));
  };
  auto finite = [](double v) { return std::isfinite(v); };

  if (!(finite(c.pitch_m) && c.pitch_m > 0.0))
    top("pitch_m", "must be > 0 m, got " + number_text(c.pitch_m));
  if (!(finite(c.gap_m) && c.gap_m >= 0.0)) top("gap_m", "must be >= 0 m, got " + number_text(c.gap_m));
  if (!(finite(c.magnet_thickness_m) && c.magnet_thickness_m > 0.0))
    top("magnet_thickness_m", "must be > 0 m, got " + number_text(c.magnet_thickness_m));
  if (!(finite(c.br_strong_t) && c.br_strong_t > 0.0))
    top("br_strong_t", "must be > 0 T, got " + number_text(c.br_strong_t));
  if (!(finite(c.br_weak_t) && c.br_weak_t >= 0.0))
    top("br_weak_t", "must be >= 0 T, got " + number_text(c.br_weak_t));
  if (c.weak_ratio && !(finite(*c.weak_ratio) && *c.weak_ratio >= 0.0))
    top("weak_ratio", "must be >= 0, got " + number_text(*c.weak_ratio));
  if (!(finite(c.sensitivity_v_per_t) && c.sensitivity_v_per_t != 0.0))
    top("sensitivity_v_per_t", "must be a non-zero number of V/T, got " +
                                   number_text(c.sensitivity_v_per_t));

  if (c.harmonics.empty() || c.harmonics.size() > HalbachHall::kMaxHarmonics) {
    top("harmonics", "needs 1 to " + std::to_string(HalbachHall::kMaxHarmonics) +
                         " harmonics, got " + std::to_string(c.harmonics.size()));
  }
  std::set<int> seen_harmonics;
  for (int n : c.harmonics) {
    if (n < 1 || n > 99 || n % 2 == 0) {
      top("harmonics", "each harmonic must be an odd integer in 1..99 (a Halbach matrix has "
                       "no even harmonics), got " + std::to_string(n));
    } else if (!seen_harmonics.insert(n).second) {
      top("harmonics", "harmonic " + std::to_string(n) + " is listed twice");
    }
  }

  if (c.sensors.empty() || c.sensors.size() > HalbachHall::kMaxSensors) {
    top("sensors", "needs 1 to " + std::to_string(HalbachHall::kMaxSensors) +
                       " sensors, got " + std::to_string(c.sensors.size()));
  }
  std::set<std::string> sensor_names;
  std::set<std::string> channel_names;
  for (std::size_t i = 0; i < c.sensors.size(); ++i) {
    const HalbachSensorConfig& s = c.sensors[i];
    auto sensor = [&](std::string_view key, std::string message) {
      fail(HalbachConfigScope::sensor, i, key, std::move(message));
    };
    if (s.name.empty()) sensor("name", "must not be empty");
    else if (!sensor_names.insert(s.name).second)
      sensor("name", "sensor '" + s.name + "' is defined twice");
    for (auto [key, v] : {std::pair<const char*, double>{"x_m", s.x_m}, {"y_m", s.y_m},
                          {"x_phase_m", s.x_phase_m}, {"y_phase_m", s.y_phase_m},
                          {"offset_v", s.offset_v[0]}, {"offset_v", s.offset_v[1]}}) {
      if (!finite(v)) sensor(key, "must be a finite number, got " + number_text(v));
    }
    if (!s.channels.empty() && s.channels.size() != 2) {
      sensor("channels", "needs exactly 2 names [a (-y aligned), b (-x aligned)], got " +
                             std::to_string(s.channels.size()));
    } else {
      for (const std::string& ch : s.channels) {
        if (ch.empty()) sensor("channels", "channel names must not be empty");
      }
      const std::vector<std::string> names =
          s.channels.empty() ? std::vector<std::string>{s.name + "_a", s.name + "_b"} : s.channels;
      for (const std::string& ch : names) {
        if (!ch.empty() && !channel_names.insert(ch).second)
          sensor("channels", "channel name '" + ch + "' is used twice");
      }
    }
  }

  if (!c.coefficients.empty()) {
    if (c.harmonics != std::vector<int>{1, 5}) {
      top("harmonics", "explicit `coefficients` (c + alpha sin(wu) + beta sin(5wu), eq. 3.12) "
                       "imply harmonics [1, 5]; remove `harmonics` or set it to [1, 5]");
    }
    if (c.coefficients.size() != 2 * c.sensors.size()) {
      top("coefficients", "needs one entry per channel (2 per sensor: " +
                              std::to_string(2 * c.sensors.size()) + "), got " +
                              std::to_string(c.coefficients.size()));
    }
    for (std::size_t i = 0; i < c.coefficients.size(); ++i) {
      const HalbachCurveFit& f = c.coefficients[i];
      for (auto [key, v] : {std::pair<const char*, double>{"c_v", f.c_v},
                            {"alpha_v", f.alpha_v}, {"beta_v", f.beta_v}}) {
        if (!finite(v))
          fail(HalbachConfigScope::coefficient, i, key, "must be a finite number, got " + number_text(v));
      }
    }
  }
  return ok;
}

// ---------------------------------------------------------------------------------------

HalbachHall::HalbachHall() { declare_measurement_elements(planar_pose(), {}); }

Status HalbachHall::configure(Params& params) {
  const HalbachHallConfig d;
  HalbachHallConfig c;
  c.pitch_m = params.number("pitch_m", d.pitch_m);
  c.gap_m = params.number("gap_m", d.gap_m);
  c.magnet_thickness_m = params.number("magnet_thickness_m", d.magnet_thickness_m);
  c.br_strong_t = params.number("br_strong_t", d.br_strong_t);
  c.br_weak_t = params.number("br_weak_t", d.br_weak_t);
  if (params.has("weak_ratio")) c.weak_ratio = params.number("weak_ratio");
  c.sensitivity_v_per_t = params.number("sensitivity_v_per_t", d.sensitivity_v_per_t);

  c.harmonics.clear();
  for (std::int64_t n : params.integers("harmonics", {1, 5})) {
    // Out-of-range values are clamped only so that validation can name them.
    c.harmonics.push_back(static_cast<int>(std::clamp<std::int64_t>(n, -1000000, 1000000)));
  }

  std::vector<Params> sensor_items = params.items("sensors");
  for (Params& item : sensor_items) {
    HalbachSensorConfig s;
    s.name = item.text("name");
    s.x_m = item.number("x_m");
    s.y_m = item.number("y_m");
    s.channels = item.texts("channels", {});
    const std::vector<double> offset = item.numbers("offset_v", {0.0, 0.0}, 2);
    s.offset_v = {offset.at(0), offset.at(1)};
    s.x_phase_m = item.number("x_phase_m", 0.0);
    s.y_phase_m = item.number("y_phase_m", 0.0);
    c.sensors.push_back(std::move(s));
  }

  std::vector<Params> coefficient_items;
  if (params.has("coefficients")) {
    coefficient_items = params.items("coefficients");
    for (Params& item : coefficient_items) {
      HalbachCurveFit f;
      f.c_v = item.number("c_v");
      f.alpha_v = item.number("alpha_v");
      f.beta_v = item.number("beta_v");
      c.coefficients.push_back(f);
    }
    // The fitted coefficients already contain gap, magnets and gain: physics keys would be
    // silently ignored, so name them.
    for (const char* key : {"gap_m", "magnet_thickness_m", "br_strong_t", "br_weak_t",
                            "weak_ratio", "sensitivity_v_per_t"}) {
      if (params.has(key)) {
        params.fail(key, std::string("is not used with explicit `coefficients` (the curve fit "
                                     "already contains the field and the gain); remove it"));
      }
    }
  }
  // Validate what was read, reporting at the exact YAML entry. sensor_items[i] and
  // c.sensors[i] come from the same loop, so indices agree even when items() dropped an entry
  // that is not a map. Problems the getters already reported are not repeated.
  validate_halbach_config(c, [&](HalbachConfigScope scope, std::size_t index,
                                 std::string_view key, std::string message) {
    switch (scope) {
      case HalbachConfigScope::top:
        if (key == "sensors" && sensor_items.empty()) return;  // items() said why
        params.fail(key, std::move(message));
        break;
      case HalbachConfigScope::sensor:
        if (key == "name" && !sensor_items.at(index).has("name")) return;  // text() said why
        sensor_items.at(index).fail(key, std::move(message));
        break;
      case HalbachConfigScope::coefficient:
        coefficient_items.at(index).fail(key, std::move(message));
        break;
    }
  });
  if (!params.ok()) return Status::error("invalid parameters");
  build(c);
  return Status::ok();
}

Status HalbachHall::apply(const HalbachHallConfig& config) {
  std::string problems;
  const bool valid = validate_halbach_config(
      config, [&](HalbachConfigScope scope, std::size_t index, std::string_view key,
                  std::string message) {
        if (!problems.empty()) problems += "; ";
        if (scope == HalbachConfigScope::sensor)
          problems += "sensors[" + std::to_string(index) + "].";
        else if (scope == HalbachConfigScope::coefficient)
          problems += "coefficients[" + std::to_string(index) + "].";
        problems += std::string(key) + ": " + message;
      });
  if (!valid) return Status::error(problems);
  build(config);
  return Status::ok();
}

void HalbachHall::build(const HalbachHallConfig& config) {
  config_ = config;
  harmonics_ = config.harmonics;
  wavenumber_rad_per_m_ = 2.0 * kPi / config.pitch_m;
  weak_ratio_ = config.weak_ratio.value_or(std::numbers::sqrt2 * config.br_weak_t /
                                           config.br_strong_t);
  const bool curve_fit = !config.coefficients.empty();

  physics_harmonics_.clear();
  if (!curve_fit) {
    for (int n : harmonics_) {
      physics_harmonics_.push_back(halbach_field_harmonic(n, config.pitch_m, config.gap_m,
                                                          config.magnet_thickness_m,
                                                          config.br_strong_t, weak_ratio_));
    }
  }

  profiles_.clear();
  geometry_.clear();
  Elements channels;
  for (std::size_t i = 0; i < config.sensors.size(); ++i) {
    const HalbachSensorConfig& s = config.sensors[i];
    geometry_.push_back({s.x_m, s.y_m});
    const std::array<std::string, 2> names =
        s.channels.empty() ? std::array<std::string, 2>{s.name + "_a", s.name + "_b"}
                           : std::array<std::string, 2>{s.channels[0], s.channels[1]};
    for (std::size_t k = 0; k < 2; ++k) {
      ChannelProfile p;
      // Channel a (-y aligned) sees B_Y of world Y, channel b (-x aligned) B_X of world X.
      p.axis = (k == 0) ? Axis::y : Axis::x;
      p.phase_m = (k == 0) ? s.y_phase_m : s.x_phase_m;
      p.dc_v = s.offset_v[k];
      if (curve_fit) {
        const HalbachCurveFit& f = config.coefficients[2 * i + k];
        p.dc_v += f.c_v;
        p.sin_v[0] = f.alpha_v;  // harmonics_ is [1, 5] (validated)
        p.sin_v[1] = f.beta_v;
      } else {
        // Both arrays have the same profile; B_Y(Y) has the form of B_X(X) (eq. 3.13/3.14).
        for (std::size_t h = 0; h < physics_harmonics_.size(); ++h) {
          p.sin_v[h] = config.sensitivity_v_per_t * physics_harmonics_[h].sin_t;
          p.cos_v[h] = config.sensitivity_v_per_t * physics_harmonics_[h].cos_t;
        }
      }
      profiles_.push_back(p);
      channels.push_back({names[k], "V"});
    }
  }
  declare_measurement_elements(planar_pose(), std::move(channels));
}

double HalbachHall::sin_coefficient_v(std::size_t channel, std::size_t h) const {
  return profiles_.at(channel).sin_v.at(h);
}
double HalbachHall::cos_coefficient_v(std::size_t channel, std::size_t h) const {
  return profiles_.at(channel).cos_v.at(h);
}
double HalbachHall::dc_v(std::size_t channel) const { return profiles_.at(channel).dc_v; }

void HalbachHall::field(const ChannelProfile& profile, double u, double& value,
                        double& slope) const noexcept {
  const double base = wavenumber_rad_per_m_ * (u - profile.phase_m);
  value = 0.0;
  slope = 0.0;
  for (std::size_t h = 0; h < harmonics_.size(); ++h) {
    const double n = harmonics_[h];
    const double s = std::sin(n * base);
    const double c = std::cos(n * base);
    value += profile.sin_v[h] * s + profile.cos_v[h] * c;
    slope += n * wavenumber_rad_per_m_ * (profile.sin_v[h] * c - profile.cos_v[h] * s);
  }
}

void HalbachHall::predict(const double* state, double* y, double* H) const noexcept {
  const double x = state[kX];
  const double yy = state[kY];
  const double theta = state[kThetaZ];
  const double ct = std::cos(theta);
  const double st = std::sin(theta);
  for (std::size_t i = 0; i < geometry_.size(); ++i) {
    const SensorGeometry& g = geometry_[i];
    // Sensor world position (eq. 4.19-4.22 with X0, Y0 as in the thesis code).
    const double lever_x = g.x_m * ct - g.y_m * st;  // Xs - x = dYs/dtheta
    const double lever_y = g.x_m * st + g.y_m * ct;  // Ys - y = -dXs/dtheta
    const double xs = x + lever_x;
    const double ys = yy + lever_y;
    const ChannelProfile& pa = profiles_[2 * i];
    const ChannelProfile& pb = profiles_[2 * i + 1];
    double field_a = 0.0;  // A = a_10 - c_a: field of world Y (eq. 4.1)
    double slope_a = 0.0;
    double field_b = 0.0;  // B = b_10 - c_b: field of world X (eq. 4.2)
    double slope_b = 0.0;
    field(pa, ys, field_a, slope_a);
    field(pb, xs, field_b, slope_b);
    // Rotation of the field part into the sensor's axes (eq. 4.23-4.26; README "Deviations" 3).
    y[2 * i] = pa.dc_v + field_a * ct + field_b * st;
    y[2 * i + 1] = pb.dc_v - field_a * st + field_b * ct;
    if (H == nullptr) continue;
    // Analytic Jacobian for any harmonics (README "Deviations" 4):
    // dA/d(x, y, th) = [0, A', A' (Xs - x)],  dB/d(x, y, th) = [B', 0, -B' (Ys - y)].
    const double da_dth = slope_a * lever_x;
    const double db_dth = -slope_b * lever_y;
    double* row_a = H + 2 * i * kStateSize;
    double* row_b = row_a + kStateSize;
    row_a[kX] = slope_b * st;
    row_a[kY] = slope_a * ct;
    row_a[kThetaZ] = da_dth * ct + db_dth * st - field_a * st + field_b * ct;
    row_b[kX] = slope_b * ct;
    row_b[kY] = -slope_a * st;
    row_b[kThetaZ] = -da_dth * st + db_dth * ct - field_a * ct - field_b * st;
  }
}

void HalbachHall::evaluate(const double* state, double* y) const noexcept {
  predict(state, y, nullptr);
}

void HalbachHall::jacobian(const double* state, double* y, double* H) const noexcept {
  predict(state, y, H);
}

double HalbachHall::max_model_error_v() const {
  double worst = 0.0;
  for (const ChannelProfile& p : profiles_) {
    for (int k = 0; k < kErrorSamplesPerPitch; ++k) {
      const double base = 2.0 * kPi * k / kErrorSamplesPerPitch;
      double error = 0.0;
      for (std::size_t h = 0; h < harmonics_.size(); ++h) {
        if (harmonics_[h] == 1 || harmonics_[h] == 5) continue;
        error += p.sin_v[h] * std::sin(harmonics_[h] * base) +
                 p.cos_v[h] * std::cos(harmonics_[h] * base);
      }
      worst = std::max(worst, std::abs(error));
    }
  }
  return worst;
}

void HalbachHall::describe(Json& out) const {
  const bool curve_fit = !config_.coefficients.empty();
  out["field_model"] = curve_fit ? "curve fit c + alpha sin(wu) + beta sin(5wu) (eq. 3.12)"
                                 : "Fourier physics (eq. 3.5, 3.6 corrected, 3.9, 3.10)";
  out["pitch_m"] = config_.pitch_m;
  out["wavenumber_rad_per_m"] = wavenumber_rad_per_m_;
  if (!curve_fit) {
    out["gap_m"] = config_.gap_m;
    out["magnet_thickness_m"] = config_.magnet_thickness_m;
    out["br_strong_t"] = config_.br_strong_t;
    out["br_weak_t"] = config_.br_weak_t;
    out["weak_ratio"] = weak_ratio_;
    out["sensitivity_v_per_t"] = config_.sensitivity_v_per_t;
    Json& harmonics = out["harmonics"];
    harmonics = Json::array();
    for (const HalbachHarmonic& h : physics_harmonics_) {
      Json item = Json::object();
      item["n"] = h.n;
      item["amplitude_t"] = h.amplitude_t();
      item["sin_v"] = config_.sensitivity_v_per_t * h.sin_t;
      item["cos_v"] = config_.sensitivity_v_per_t * h.cos_t;
      harmonics.push(std::move(item));
    }
  }
  Json& sensors = out["sensors"];
  sensors = Json::array();
  for (std::size_t i = 0; i < config_.sensors.size(); ++i) {
    const HalbachSensorConfig& s = config_.sensors[i];
    Json item = Json::object();
    item["name"] = s.name;
    item["x_m"] = s.x_m;
    item["y_m"] = s.y_m;
    item["x_phase_m"] = s.x_phase_m;
    item["y_phase_m"] = s.y_phase_m;
    Json& channels = item["channels"];
    channels = Json::array();
    for (std::size_t k = 0; k < 2; ++k) {
      const ChannelProfile& p = profiles_[2 * i + k];
      Json ch = Json::object();
      ch["name"] = this->channels()[2 * i + k].name;
      ch["field"] = (p.axis == Axis::y) ? "B_Y(world Y)" : "B_X(world X)";
      ch["dc_v"] = p.dc_v;
      ch["sin_v"] = std::vector<double>(p.sin_v.begin(), p.sin_v.begin() + harmonics_.size());
      ch["cos_v"] = std::vector<double>(p.cos_v.begin(), p.cos_v.begin() + harmonics_.size());
      channels.push(std::move(ch));
    }
    sensors.push(std::move(item));
  }
  // What an estimator using only the fundamental and 5th misses of this field.
  out["max_model_error_vs_harmonics_1_5_v"] = max_model_error_v();
}

namespace {

constexpr ParamDoc kParams[] = {
    {"pitch_m", "number", "0.0508", "spatial period l of the magnet matrix, > 0"},
    {"gap_m", "number", "0.002", "sensor height Z0 above the magnet surface, >= 0 (physics only)"},
    {"magnet_thickness_m", "number", "0.0127", "magnet layer thickness Delta (eq. 3.9/3.10)"},
    {"br_strong_t", "number", "1.43", "remanence of the vertical magnets (NdFeB50)"},
    {"br_weak_t", "number", "1.10", "remanence of the 45-degree magnets (NdFeB30)"},
    {"weak_ratio", "number", "sqrt(2)*br_weak_t/br_strong_t",
     "horizontal/vertical magnetisation ratio r of one array (README: Deviations 2)"},
    {"sensitivity_v_per_t", "number", "8.43",
     "end-to-end gain sensor x amplifier at the ADC, non-zero (sign = orientation)"},
    {"harmonics", "list<integer>", "[1, 5]", "odd spatial harmonics of the field model (1..99)"},
    {"sensors", "list<map>", nullptr,
     "{name, x_m, y_m, channels: [a, b] (default <name>_a, <name>_b), offset_v: [ca, cb] "
     "(default [0, 0]), x_phase_m, y_phase_m (default 0)}; body-frame position to the CoM"},
    {"coefficients", "list<map>", "none (Fourier physics)",
     "curve fit per channel {c_v, alpha_v, beta_v}: c + alpha sin(wu) + beta sin(5wu) (eq. 3.12)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::HalbachHall, "sensor.halbach_hall", lode::PluginKind::sensor, "0.1.0",
            "Two-axis Hall sensors over a Halbach magnet matrix (Kawato ch. 3-4), analytic Jacobian",
            lode::plugins::kParams, lode::kNoPorts)
