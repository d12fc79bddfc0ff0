// sensor.halbach_hall: two-axis Hall sensors on a platen over a Halbach magnet matrix.
//
// The measurement model of Kawato's ATP stage (Kawato 2005, ch. 3-4): each
// sensor measures the two in-plane field components of a concentrated-field Halbach matrix,
// which is the superposition of two orthogonal 1-D Halbach arrays, so the X component depends
// only on the sensor's world X and the Y component only on its world Y (eq. 3.13/3.14).
//
// Per axis the field profile is a sum of odd spatial harmonics (w = 2 pi / pitch):
//   f(u) = sum_n ( s_n sin(n w u') + k_n cos(n w u') ),   u' = u - phase offset
// with s_n, k_n either from the Fourier physics of the magnets (eq. 3.5, 3.6, 3.9, 3.10 with
// its sign corrected, README "Deviations", evaluated once at configure time) or from explicit
// curve-fit coefficients c + alpha sin(w u') + beta sin(5 w u') (eq. 3.12, 4.1-4.4 without the
// cross-axis terms zeta, delta, as the thesis finally used them).
//
// Channels of sensor s at body position (xs, ys), platen pose (x, y, theta):
//   Xs = x + xs cos th - ys sin th,     Ys = y + xs sin th + ys cos th     (eq. 4.19-4.22)
//   A = f_a(Ys),  B = f_b(Xs)           (field parts before rotation, eq. 4.1-4.4)
//   a = c_a + A cos th + B sin th,  b = c_b - A sin th + B cos th        (eq. 4.23-4.26,
//   rotating only the field part, README "Deviations"; the DC term is an electronic offset)
// a is the channel aligned with -y (sees B_Y), b the one aligned with -x (sees B_X).
//
// @sensor
// state:                       # what the model depends on
//   - x: m
//   - y: m
//   - theta_z: rad
// channels:                    # two per sensor, in the order of `sensors`
//   - <sensor>_a: V            # -y aligned: field of world Y   (thesis a1 / c1)
//   - <sensor>_b: V            # -x aligned: field of world X   (thesis b1 / d2)
// @endsensor
//
// Threads: configure()/apply()/describe() on the loader thread; evaluate()/jacobian() on the
// RT thread (no allocation, no throw, no I/O).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// One two-axis Hall sensor; the YAML keys of a `sensors` entry have the same names.
struct HalbachSensorConfig {
  std::string name;
  double x_m = 0.0;  ///< body-frame position relative to the platen's centre of mass
  double y_m = 0.0;
  /// Channel names [a, b]; empty means `<name>_a`, `<name>_b`.
  std::vector<std::string> channels;
  std::array<double, 2> offset_v{};  ///< DC offset of channel a and b [V]
  double x_phase_m = 0.0;  ///< phase offset of the X field seen by this sensor (X_off, eq. 4.2)
  double y_phase_m = 0.0;  ///< phase offset of the Y field seen by this sensor (Y_off, eq. 4.1)
};

/// Explicit curve-fit coefficients of one channel (eq. 3.12): c + alpha sin(wu) + beta sin(5wu).
struct HalbachCurveFit {
  double c_v = 0.0;
  double alpha_v = 0.0;
  double beta_v = 0.0;
};

/// All parameters; the YAML keys have the same names.
struct HalbachHallConfig {
  double pitch_m = 0.0508;              ///< spatial period l of the matrix (2 in)
  double gap_m = 0.002;                 ///< sensor height Z0 above the magnet surface
  double magnet_thickness_m = 0.0127;   ///< magnet thickness Delta (eq. 3.9/3.10)
  double br_strong_t = 1.43;            ///< remanence of the vertical (strong) magnets
  double br_weak_t = 1.10;              ///< remanence of the 45-degree (weak) magnets
  std::optional<double> weak_ratio;     ///< overrides sqrt(2) br_weak / br_strong
  double sensitivity_v_per_t = 8.43;    ///< end-to-end volts per tesla (0.4 V/T x 21.07)
  std::vector<int> harmonics{1, 5};     ///< odd spatial harmonics in the model
  std::vector<HalbachSensorConfig> sensors;
  std::vector<HalbachCurveFit> coefficients;  ///< empty: physics; else one per channel
};

/// Where a configuration problem is: the model's top level, a `sensors` entry or a
/// `coefficients` entry (so configure(Params&) can report it at the right YAML position).
enum class HalbachConfigScope { top, sensor, coefficient };
using HalbachConfigReporter =
    std::function<void(HalbachConfigScope scope, std::size_t index, std::string_view key,
                       std::string message)>;

/// Report every problem of `config`; returns true when there is none.
bool validate_halbach_config(const HalbachHallConfig& config, const HalbachConfigReporter& report);

/// The Fourier coefficients of the lateral field B_X(X) of one 1-D array, strong side up:
/// B_X(X) = sin_t sin(n w X) + cos_t cos(n w X) (eq. 3.5, 3.6 corrected, 3.10, 3.14).
struct HalbachHarmonic {
  int n = 1;
  double sin_t = 0.0;
  double cos_t = 0.0;
  [[nodiscard]] double amplitude_t() const;
};
HalbachHarmonic halbach_field_harmonic(int n, double pitch_m, double gap_m,
                                       double magnet_thickness_m, double br_strong_t,
                                       double weak_ratio);

class HalbachHall final : public MeasurementModel {
 public:
  static constexpr std::size_t kMaxHarmonics = 8;
  static constexpr std::size_t kMaxSensors = 8;
  static constexpr std::size_t kStateSize = 3;
  enum StateIndex : std::size_t { kX = 0, kY, kThetaZ };

  HalbachHall();

  Status configure(Params& params) override;
  /// Validate and use `config`; configure() ends here. Tests call it directly to exercise the
  /// physics without a YAML file. On failure the message lists every problem.
  Status apply(const HalbachHallConfig& config);
  [[nodiscard]] const HalbachHallConfig& config() const { return config_; }

  void evaluate(const double* state, double* y) const noexcept override;
  void jacobian(const double* state, double* y, double* H) const noexcept override;
  void describe(Json& out) const override;

  /// Effective horizontal/vertical magnetisation ratio r used by the physics (README "Deviations").
  [[nodiscard]] double effective_weak_ratio() const { return weak_ratio_; }
  /// Harmonic numbers, in configuration order.
  [[nodiscard]] const std::vector<int>& harmonics() const { return harmonics_; }
  /// Sine and cosine coefficient [V] of harmonic index h (into harmonics()) of channel c.
  [[nodiscard]] double sin_coefficient_v(std::size_t channel, std::size_t h) const;
  [[nodiscard]] double cos_coefficient_v(std::size_t channel, std::size_t h) const;
  /// DC term [V] of channel c (offset_v, plus c_v with explicit coefficients).
  [[nodiscard]] double dc_v(std::size_t channel) const;
  /// max over a pitch and over channels of |f(u) - (harmonics 1 and 5 of f)(u)| [V].
  [[nodiscard]] double max_model_error_v() const;

 private:
  enum class Axis { x, y };
  /// One channel's field profile: f(u) = sum_h sin_v[h] sin(n_h w (u - phase)) + cos_v[h] cos(..).
  struct ChannelProfile {
    Axis axis = Axis::x;
    double dc_v = 0.0;
    double phase_m = 0.0;
    std::array<double, kMaxHarmonics> sin_v{};
    std::array<double, kMaxHarmonics> cos_v{};
  };
  struct SensorGeometry {
    double x_m = 0.0;
    double y_m = 0.0;
  };

  /// Build the channel profiles from an already valid configuration.
  void build(const HalbachHallConfig& config);
  /// f(u) and df/du of one channel's field part (without the DC term).
  void field(const ChannelProfile& profile, double u, double& value, double& slope) const noexcept;
  /// Shared by evaluate() and jacobian(); H may be nullptr.
  void predict(const double* state, double* y, double* H) const noexcept;

  HalbachHallConfig config_;
  std::vector<int> harmonics_;
  std::vector<HalbachHarmonic> physics_harmonics_;  ///< per harmonic, in T (physics mode)
  std::vector<ChannelProfile> profiles_;            ///< 2 per sensor: a, b
  std::vector<SensorGeometry> geometry_;
  double wavenumber_rad_per_m_ = 0.0;
  double weak_ratio_ = 0.0;
};

}  // namespace lode::plugins
