// sensor.sincos_encoder: a linear analog (sin/cos) encoder read head over a periodic scale.
//
// Zimmerman, Oshman & Brandes 2006 (Fig. 1): the read head produces two
// sinusoids of one scale period, equal amplitude V, 90 degrees apart (eq. 1, 4):
//
//   h(x) = [ V sin(2 pi f_s x) ; V cos(2 pi f_s x) ],   f_s = 1 / pitch_m   [1/m]
//
// f_s is the *spatial* frequency of the scale, not a sampling rate. Its Jacobian is the
// corrected eq. 11 (the trig arguments are 2 pi f_s x, not x as printed):
//
//   dh/dx = 2 pi f_s V [ cos(2 pi f_s x) ; -sin(2 pi f_s x) ]
//
// The paper models ideal signals. As an optional extension (not in the paper; defaults
// reproduce the paper exactly) the model can add what real read heads show
// and what the cited calibration papers remove: per-channel DC offsets, a cosine/sine
// amplitude ratio and a quadrature (phase) error phi:
//
//   h(x) = [ V sin(theta) + o_sin ;  r V cos(theta + phi) + o_cos ],   theta = 2 pi x / pitch
//
// @sensor
// state:                   # what the model depends on
//   - x: m                 # absolute position of the read head along the scale
// channels:                # names configurable, default sin, cos
//   - sin: V
//   - cos: V
// @endsensor
//
// Used twice: io.sim evaluates it to synthesise the encoder signals, and
// estimator.ekf_encoder uses evaluate()/jacobian() as its measurement model.
//
// Threads: configure()/apply()/describe() on the loader thread; evaluate()/jacobian() on the
// RT thread (no allocation, no throw, no I/O).
#pragma once

#include <array>
#include <cstddef>
#include <string>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// All parameters; the YAML keys have the same names.
struct SincosEncoderConfig {
  double pitch_m = 4e-6;       ///< scale period (Table 1: 4 um; experiment, Table 5: 20 um)
  double amplitude_v = 1.0;    ///< V of eq. 1 (Table 1: 1 V)
  std::array<std::string, 2> channel_names{"sin", "cos"};
  std::array<double, 2> offset_v{};   ///< DC offsets of the sin and cos channel (extension)
  double amplitude_ratio = 1.0;       ///< cos amplitude / sin amplitude (extension)
  double quadrature_error_rad = 0.0;  ///< phase error of the cos channel (extension)
};

class SincosEncoder final : public MeasurementModel {
 public:
  static constexpr std::size_t kStateSize = 1;
  static constexpr std::size_t kChannelCount = 2;
  enum ChannelIndex : std::size_t { kSin = 0, kCos = 1 };

  SincosEncoder();

  Status configure(Params& params) override;
  /// Validate and use `config`; configure() ends here. Tests call it directly.
  Status apply(const SincosEncoderConfig& config);
  [[nodiscard]] const SincosEncoderConfig& config() const { return config_; }

  void evaluate(const double* state, double* y) const noexcept override;
  void jacobian(const double* state, double* y, double* H) const noexcept override;
  void describe(Json& out) const override;

  /// theta = 2 pi x / pitch reduced to [-pi, pi): the reduction is done on x / pitch in
  /// cycles first, so a position many periods from the origin keeps its full precision.
  [[nodiscard]] double phase_rad(double position_m) const noexcept;
  /// 2 pi f_s = 2 pi / pitch [rad/m].
  [[nodiscard]] double wavenumber_rad_per_m() const noexcept { return wavenumber_rad_per_m_; }

 private:
  SincosEncoderConfig config_;
  double wavenumber_rad_per_m_ = 0.0;
  double cos_amplitude_v_ = 0.0;  ///< amplitude_ratio * amplitude_v
};

}  // namespace lode::plugins
