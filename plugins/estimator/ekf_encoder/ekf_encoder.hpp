// estimator.ekf_encoder: 3-state extended Kalman filter that decodes analog sin/cos encoder
// signals into absolute position, velocity and acceleration (Zimmerman, Oshman & Brandes
// 2006, eqs. 6-16).
//
// Process model: the Singer model, acceleration a first-order Gauss-Markov process with pole
// alpha (eq. 6-7), discretised exactly over the sample time T (eq. 8-10):
//
//   x = [x, v, a],   x(k+1) = F x(k) + w_d(k)
//   F = [[1, T, (aT - 1 + e^-aT)/a^2], [0, 1, (1 - e^-aT)/a], [0, 0, e^-aT]]        (9)
//   Q_d from (10a-f) *as printed*, sigma_m^2 = acceleration_variance_m2_s4 (the printed
//   entries are Singer's for a white-noise PSD of 2 alpha sigma_m^2, so sigma_m^2 is the
//   steady-state acceleration variance [(m/s^2)^2], whatever Table 1's unit says; this
//   reading reproduces the paper's Fig. 6, the literal-PSD one does not: README).
//
// (10a-b) cancel catastrophically for small alpha T (the bracket of q11 is ~(alpha T)^5/10),
// so Q_d is evaluated from the Taylor series of each bracket when alpha T < 0.5 and from the
// printed closed form otherwise; describe() shows both and their difference.
//
// Measurement model: any lode::MeasurementModel with one state element (position [m]) and
// 1-4 channels [V], normally sensor.sincos_encoder: h(x) and dh/dx (the corrected eq. 11).
// The filter carries the *absolute* position: h is periodic, so no unwrapping is needed
// while the one-step prediction error stays well below pitch / (2 pi).
//
// Recursion per sample (eq. 12-16), with R = diag(noise_std_v^2):
//   x(k+1|k) = F x(k|k),  P(k+1|k) = F P(k|k) F' + Q_d                        (12, 13)
//   K = P H' (H P H' + R)^-1,  H = [dh/dx 0 0] at x(k+1|k)                      (15, 11)
//   x(k+1|k+1) = x(k+1|k) + K (z - h(x(k+1|k)))                                 (14)
//   P(k+1|k+1) = (I - K H) P (I - K H)' + K R K'   (Joseph form)                (16)
// H has one non-zero column, so K = P e1 w' with w = S^-1 dh/dx; the code uses that
// structure (scalars w'h, w'Rw, w'(z - h)) instead of 3 x m products, same numbers.
//
// Initialisation (not in the paper): x(0) = [first coarse position, 0, 0] from the
// optional `initial` input (normally the arctangent decoder's first sample) or
// initial_position_m, P(0) = diag(initial_*_std^2); the first sample is then used for a
// measurement update.
//
// @system
// name: estimator.ekf_encoder
// input_ports:
//   signals: [model channels, V]        # e.g. io.sim signals: sin, cos
//   initial: [x m, ...], optional       # coarse position for the first sample (e.g. arctan.estimate)
// output_ports:
//   estimate:     [x m, v m/s]          # x(k|k): absolute position and velocity
//   acceleration: [a m/s^2]
//   std:          [x_std m, v_std m/s, a_std m/s^2]   # sqrt(diag P(k|k))
//   innovation:   [model channels, V]   # z - h(x(k|k-1))
// @endsystem
//
// Sized path: two channels (sin, cos: config/encoder_ekf.yaml) run the update on 2 x 2 storage
// sized at compile time (compile_time_sizes: true, the default); any other count, or
// compile_time_sizes: false, the capacity-4 dynamic code. Same operations in the same order:
// the same bits (a test compares both cycle by cycle).
//
// Threads: configure()/activate()/describe() on the loader thread; step() on the RT thread
// (fixed-size Eigen only; no allocation).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"

namespace lode::plugins {

namespace ekf_encoder {

/// Named state indices.
inline constexpr int kPosition = 0;
inline constexpr int kVelocity = 1;
inline constexpr int kAcceleration = 2;
inline constexpr int kStateSize = 3;
inline constexpr std::size_t kMaxChannels = 4;

using StateVector = Eigen::Matrix<double, kStateSize, 1>;
using StateMatrix = Eigen::Matrix<double, kStateSize, kStateSize>;
using ChannelVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, static_cast<int>(kMaxChannels), 1>;
using ChannelMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, static_cast<int>(kMaxChannels),
                                    static_cast<int>(kMaxChannels)>;
/// The channel count of the sized path: a sin/cos head.
inline constexpr int kSizedChannels = 2;
using SizedChannelVector = Eigen::Matrix<double, kSizedChannels, 1>;
using SizedChannelMatrix = Eigen::Matrix<double, kSizedChannels, kSizedChannels>;

/// F = e^{A T} of the Singer model (eq. 9), evaluated without cancellation for small alpha T.
StateMatrix singer_transition(double alpha_rad_s, double period_s);

/// Q_d of eq. (10a-f) with sigma_m^2 = acceleration_variance, each bracket from its Taylor
/// series when alpha T < kSeriesThreshold (no cancellation), else from the closed form.
StateMatrix singer_process_noise(double alpha_rad_s, double period_s, double acceleration_variance);

/// Q_d of eq. (10a-f) exactly as printed, in plain double arithmetic (for cross-checks: it
/// loses ~log10(1/(alpha T)^5) digits to cancellation).
StateMatrix singer_process_noise_as_printed(double alpha_rad_s, double period_s,
                                            double acceleration_variance);

/// Below this alpha T the brackets of eq. (10) come from their Taylor series.
inline constexpr double kSeriesThreshold = 0.5;

/// Steady state of the recursion (12)-(16) for a position-only measurement with variance
/// r_eq = 1 / (h' R^-1 h) (the information of all channels; with R = r I and the sin/cos
/// model it does not depend on the phase).
struct SteadyState {
  StateMatrix prior_cov = StateMatrix::Zero();      ///< P(k+1|k)
  StateMatrix posterior_cov = StateMatrix::Zero();  ///< P(k|k)
  StateVector gain = StateVector::Zero();           ///< K H = gain * e1' (position-equivalent gain)
  std::array<std::array<double, 2>, kStateSize> poles{};  ///< eig of F (I - K H), (re, im)
  int iterations = 0;
  bool converged = false;
};
inline constexpr double kRiccatiTolerance = 1e-13;
inline constexpr int kRiccatiMaxIterations = 5'000'000;

SteadyState steady_state(const StateMatrix& transition, const StateMatrix& process_noise,
                         double position_variance, const StateMatrix& initial_cov);

/// The filter itself, independent of ports (tests drive it directly).
class Filter {
 public:
  /// channels = m <= kMaxChannels; noise_variance has m entries. compile_time_sizes: m =
  /// kSizedChannels runs the update on storage sized at compile time (same results).
  void configure(const StateMatrix& transition, const StateMatrix& process_noise,
                 const std::vector<double>& noise_variance, const StateVector& initial_std,
                 bool compile_time_sizes = true);

  /// x(0|-1) = [position, 0, 0], P = P0.
  void reset(double position_m) noexcept;
  /// Time update (12, 13).
  void predict() noexcept;
  /// Measurement update (11, 14-16). `predicted` = h(x(k|k-1)), `slope` = dh/dx there,
  /// `measured` = z, each m long. Returns false (filter unchanged) when S is not positive
  /// definite or the result is not finite.
  bool update(const double* measured, const double* predicted, const double* slope) noexcept;

  [[nodiscard]] const StateVector& state() const noexcept { return x_; }
  [[nodiscard]] const StateMatrix& covariance() const noexcept { return p_; }
  [[nodiscard]] std::size_t channels() const noexcept { return channels_; }
  [[nodiscard]] const ChannelVector& innovation() const noexcept { return innovation_; }
  /// True when update() runs the compile-time-sized code.
  [[nodiscard]] bool fixed_size() const noexcept { return sized_; }

 private:
  /// update() on channel storage of type Vector / Matrix (dynamic, or kSizedChannels).
  template <typename Vector, typename Matrix>
  bool update_with(const Matrix& r, const double* measured, const double* predicted, const double* slope) noexcept;

  std::size_t channels_ = 0;
  StateMatrix f_ = StateMatrix::Identity();
  StateMatrix q_ = StateMatrix::Zero();
  ChannelMatrix r_;
  bool sized_ = false;
  SizedChannelMatrix sized_r_ = SizedChannelMatrix::Zero();  ///< r_ when sized_
  StateMatrix p0_ = StateMatrix::Identity();
  StateVector x_ = StateVector::Zero();
  StateMatrix p_ = StateMatrix::Identity();
  ChannelVector innovation_;
};

}  // namespace ekf_encoder

class EkfEncoder final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  [[nodiscard]] const ekf_encoder::Filter& filter() const noexcept { return filter_; }

 private:
  void write_outputs() noexcept;

  // Parameters
  std::string model_name_;
  double alpha_rad_s_ = 0.0;
  double acceleration_variance_ = 0.0;
  std::vector<double> noise_std_v_;
  ekf_encoder::StateVector initial_std_ = ekf_encoder::StateVector::Zero();
  double initial_position_m_ = 0.0;
  double period_s_ = 0.0;
  bool compile_time_sizes_ = true;

  // Model and derived matrices
  ModelPtr<MeasurementModel> model_;
  std::size_t channel_count_ = 0;
  ekf_encoder::StateMatrix transition_ = ekf_encoder::StateMatrix::Identity();
  ekf_encoder::StateMatrix process_noise_ = ekf_encoder::StateMatrix::Zero();
  ekf_encoder::Filter filter_;

  // Ports
  InputPort signals_;
  InputPort initial_;
  OutputPort estimate_;
  OutputPort acceleration_;
  OutputPort std_;
  OutputPort innovation_;

  // Cycle state and scratch (sized by kMaxChannels, no allocation)
  bool first_cycle_ = true;
  std::array<double, ekf_encoder::kMaxChannels> predicted_{};
  std::array<double, ekf_encoder::kMaxChannels> slope_{};
};

}  // namespace lode::plugins
