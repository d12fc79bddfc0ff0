// estimator.kalman: per-axis linear Kalman filter after the GLSDC (Kawato 2005,
// Table III, eq. 4.35-4.41).
//
// @system
// name: estimator.kalman
// input_ports:
//   measurement: n elements (n <= 6), any names and units        # e.g. glsdc.pose: x [m], y [m], theta_z [rad]
//   covariance:  n*n, row-major, optional                        # R_k from the GLSDC (eq. 4.28); diagonal used
// output_ports:
//   pose:         n, same names and units as the measurement     # x^-_{k+1} (predicted) or x^+_k (filtered)
//   velocity:     n, <name>_dot  [<unit>/s]
//   acceleration: n, <name>_ddot [<unit>/s^2]                    # constant_acceleration only
//   innovation:   n, same names and units as the measurement     # y_k - H x^-_k
// @endsystem
//
// Per axis (a diagonal R decouples the thesis's 9-state filter into three 3-state filters):
//   state x = [position, velocity, acceleration] (constant_acceleration, eq. 4.35) or
//             [position, velocity]               (constant_velocity)
//   Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]], Upsilon = [T^3/6, T^2/2, T]   (eq. 4.39)
//   Phi = [[1, T], [0, 1]],                      Upsilon = [T^2/2, T]          (constant velocity)
//   H = [1 0 0] (eq. 4.40), Q_k = q (eq. 4.41, m^2/s^6 for CA, m^2/s^4 for CV)
// and every cycle, exactly Table III:
//   K    = P^- H^T (H P^- H^T + R)^-1
//   x^+  = x^- + K (y - H x^-)
//   P^+  = (I - K H) P^- (I - K H)^T + K R K^T        (Joseph form, see covariance_step)
//   x^-  = Phi x^+,   P^- = Phi P^+ Phi^T + Upsilon q Upsilon^T
// invalid_measurement: predict turns a non-finite y_k(i) (or a non-finite or non-positive
// R_k(i,i)) into a time update of that axis alone (x^-_{k+1} = Phi x^-_k, P^-_{k+1} =
// Phi P^-_k Phi^T + Upsilon q Upsilon^T): the filter coasts instead of faulting.
// At 800 Hz (T = 1.25 ms) with q = 100 m^2/s^6 and r = 2.2e-10 m^2 the steady gain is
// K = [0.197, 17.2 1/s, 755 1/s^2] and the error poles sit at |ln z|/T ~ 88 rad/s (r fitted
// here to Table IV; the thesis prints no gains).
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "estimator/linear_axes.hpp"
#include "estimator/position_gain.hpp"
#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"

namespace lode::plugins {

namespace kalman {

using estimator::kAcceleration;
using estimator::kMaxAxes;
using estimator::kPosition;
using estimator::kVelocity;

enum class Motion { constant_velocity, constant_acceleration };
using estimator::OutputTiming;
/// A non-finite or non-positive R(i,i) counts as an invalid measurement too.
using estimator::InvalidMeasurement;

/// Discrete model of one axis with N states (2: constant velocity, 3: constant acceleration):
/// Phi and Upsilon of eq. 4.39 (or of the constant-velocity model) and the Q_k of eq. 4.41.
template <int N>
struct AxisModel : estimator::MotionModel<N> {
  using Matrix = typename estimator::MotionModel<N>::Matrix;
  using Vector = typename estimator::MotionModel<N>::Vector;

  double q = 0.0;  ///< Q_k of eq. 4.41 (jerk variance for CA, acceleration variance for CV)

  /// Phi and Upsilon for period t_s, with Q_k = q_value.
  static AxisModel make(double t_s, double q_value) {
    AxisModel m;
    static_cast<estimator::MotionModel<N>&>(m) = estimator::MotionModel<N>::make(t_s);
    m.q = q_value;
    return m;
  }

  /// Upsilon Q Upsilon^T: the process-noise covariance added in the propagation.
  [[nodiscard]] Matrix process_noise() const { return this->upsilon * q * this->upsilon.transpose(); }
};

/// One covariance step of Table III at measurement variance r (H = [1 0 ...]):
///   K = P^- H^T (H P^- H^T + r)^-1,  P^+ = (I - K H) P^- (I - K H)^T + K r K^T,
///   P^-_{k+1} = Phi P^+ Phi^T + Upsilon q Upsilon^T (then symmetrised).
/// The Joseph form keeps P^+ symmetric positive semidefinite for any gain and under
/// rounding; the short form (I - K H) P^- subtracts nearly equal products and drifts
/// asymmetric (and can lose definiteness) when the entries span many decades: at q = 100,
/// r = 2.2e-10 the steady P^- runs from 5.4e-11 m^2 (position) to 2.9e-3 m^2/s^4
/// (acceleration), 8 decades. Its cost (two more N x N products) is negligible at 800 Hz.
/// Symmetrising after the propagation removes the last rounding asymmetry.
template <int N>
inline void covariance_step(const AxisModel<N>& model,
                            const typename AxisModel<N>::Matrix& process_noise,
                            const typename AxisModel<N>::Matrix& prior_cov, double r,
                            typename AxisModel<N>::Vector& gain,
                            typename AxisModel<N>::Matrix& next_prior_cov) noexcept {
  using Matrix = typename AxisModel<N>::Matrix;
  gain = prior_cov.col(0) / (prior_cov(0, 0) + r);
  const Matrix i_minus_kh = estimator::i_minus_kh(gain);
  const Matrix posterior_cov =
      i_minus_kh * prior_cov * i_minus_kh.transpose() + (gain * r) * gain.transpose();
  next_prior_cov = model.phi * posterior_cov * model.phi.transpose() + process_noise;
  next_prior_cov = 0.5 * (next_prior_cov + next_prior_cov.transpose()).eval();
}

/// Time update alone (no measurement): P^-_{k+1} = Phi P^-_k Phi^T + Upsilon q Upsilon^T,
/// symmetrised. Used when a measurement is invalid and the axis coasts
/// (invalid_measurement: predict).
template <int N>
inline void covariance_predict(const AxisModel<N>& model, const typename AxisModel<N>::Matrix& process_noise,
                               const typename AxisModel<N>::Matrix& prior_cov,
                               typename AxisModel<N>::Matrix& next_prior_cov) noexcept {
  next_prior_cov = model.phi * prior_cov * model.phi.transpose() + process_noise;
  next_prior_cov = 0.5 * (next_prior_cov + next_prior_cov.transpose()).eval();
}

/// One axis of the filter: fixed-size state and covariance, no allocation anywhere.
/// A cycle is computed into a Cycle (compute_update() or compute_coast()) and committed only
/// once every axis has succeeded, so a fault on one axis leaves all of them as they were.
template <int N>
class AxisFilter {
 public:
  using Matrix = typename AxisModel<N>::Matrix;
  using Vector = typename AxisModel<N>::Vector;

  /// What one cycle produces, before it is committed. No initial values: compute_update() and
  /// compute_coast() write every member, and the block keeps one per axis on the stack of
  /// each step (filling them first cost about as much as the filters' arithmetic).
  struct Cycle {
    Vector next_prior_state;    ///< x^-_{k+1}
    Matrix next_prior_cov;      ///< P^-_{k+1}
    Vector posterior_state;     ///< x^+_k (= x^-_k when coasting)
    Vector gain;
    double innovation;          ///< y_k - H x^-_k (0 when coasting)
    double innovation_variance; ///< S = H P^-_k H^T + r (0 when coasting)
    bool updated;               ///< false: time update only
  };

  void configure(const AxisModel<N>& model, double p0) {
    model_ = model;
    process_noise_ = model.process_noise();
    p0_ = p0;
    reset();
  }

  /// Thesis initialisation: x^-_0 = 0, P^-_0 = p0 I.
  void reset() noexcept {
    prior_state_.setZero();
    prior_cov_ = p0_ * Matrix::Identity();
    posterior_state_.setZero();
    gain_.setZero();
    innovation_ = 0.0;
    innovation_variance_ = 0.0;
  }

  /// Measurement update and propagation of Table III with measurement variance r > 0. With
  /// `start_at_measurement` the prior position is first set to the measurement (the block's
  /// initialize_from_first_measurement). False if the result is not finite.
  bool compute_update(double measurement, double r, bool start_at_measurement, Cycle& out) const noexcept {
    Vector prior_state = prior_state_;
    if (start_at_measurement) prior_state(kPosition) = measurement;
    const double innovation = measurement - prior_state(kPosition);
    covariance_step(model_, process_noise_, prior_cov_, r, out.gain, out.next_prior_cov);
    out.posterior_state = prior_state + out.gain * innovation;
    out.next_prior_state = model_.phi * out.posterior_state;
    out.innovation = innovation;
    out.innovation_variance = prior_cov_(0, 0) + r;  // H P^- H^T + R, the gain's denominator
    out.updated = true;
    return out.next_prior_state.allFinite() && out.next_prior_cov.allFinite() && out.next_prior_cov(0, 0) > 0.0;
  }

  /// Time update only (coasting): x^+_k = x^-_k, x^-_{k+1} = Phi x^-_k, P as covariance_predict.
  bool compute_coast(Cycle& out) const noexcept {
    covariance_predict(model_, process_noise_, prior_cov_, out.next_prior_cov);
    out.posterior_state = prior_state_;
    out.next_prior_state = model_.phi * prior_state_;
    out.gain = gain_;
    out.innovation = 0.0;
    out.innovation_variance = 0.0;
    out.updated = false;
    return out.next_prior_state.allFinite() && out.next_prior_cov.allFinite() && out.next_prior_cov(0, 0) > 0.0;
  }

  void commit(const Cycle& c) noexcept {
    prior_state_ = c.next_prior_state;
    prior_cov_ = c.next_prior_cov;
    posterior_state_ = c.posterior_state;
    gain_ = c.gain;
    innovation_ = c.innovation;
    innovation_variance_ = c.innovation_variance;
  }

  /// Hot-swap warm start: the prior of the coming cycle (P must be symmetric positive definite).
  void set_prior(const Vector& state, const Matrix& cov) noexcept {
    prior_state_ = state;
    prior_cov_ = cov;
  }

  [[nodiscard]] const Vector& predicted() const noexcept { return prior_state_; }   ///< x^-_{k+1}
  [[nodiscard]] const Vector& filtered() const noexcept { return posterior_state_; }  ///< x^+_k
  [[nodiscard]] const Matrix& prior_covariance() const noexcept { return prior_cov_; }
  [[nodiscard]] const Vector& gain() const noexcept { return gain_; }
  [[nodiscard]] double innovation() const noexcept { return innovation_; }
  [[nodiscard]] double innovation_variance() const noexcept { return innovation_variance_; }
  [[nodiscard]] double p0() const noexcept { return p0_; }
  [[nodiscard]] const AxisModel<N>& model() const noexcept { return model_; }

 private:
  AxisModel<N> model_;
  Matrix process_noise_ = Matrix::Zero();
  double p0_ = 1e-8;
  Vector prior_state_ = Vector::Zero();
  Matrix prior_cov_ = Matrix::Identity();
  Vector posterior_state_ = Vector::Zero();
  Vector gain_ = Vector::Zero();
  double innovation_ = 0.0;
  double innovation_variance_ = 0.0;
};

/// Steady-state solution of the Table III recursion at constant r (off the RT thread).
template <int N>
struct SteadyState {
  typename AxisModel<N>::Vector gain = AxisModel<N>::Vector::Zero();
  typename AxisModel<N>::Matrix prior_cov = AxisModel<N>::Matrix::Zero();
  /// Eigenvalues z of the a-priori error dynamics Phi (I - K H), as (re, im).
  std::array<std::array<double, 2>, N> poles{};
  int iterations = 0;
  bool converged = false;
};

/// Relative change of every gain element between two Riccati iterations that counts as
/// converged, and the iteration budget (q = 0 converges only like 1/k and never meets it).
inline constexpr double kRiccatiTolerance = 1e-12;
inline constexpr int kRiccatiMaxIterations = 1'000'000;

template <int N>
SteadyState<N> steady_state(const AxisModel<N>& model, double r, double p0);

}  // namespace kalman

class KalmanEstimator final : public Block, public EstimatorState {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// @name Estimator state (hot swap). Layout per axis, axis-major: <n> [u], <n>_dot [u/s]
  /// (and <n>_ddot [u/s^2] for constant_acceleration), with the full block-diagonal
  /// covariance. The exported state is the prior of the coming step, x^-_k and P^-_k.
  //@{
  [[nodiscard]] StateLayout state_layout() const override;
  void export_state(double* values, double* covariance) const noexcept override;
  void import_state(const double* values, const double* covariance, const std::uint8_t* present) noexcept override;
  [[nodiscard]] std::size_t innovation_size() const override { return axes_; }
  bool innovation(double* residual, double* variance) const noexcept override;
  //@}

 private:
  [[nodiscard]] int states_per_axis() const noexcept {
    return motion_ == kalman::Motion::constant_acceleration ? 3 : 2;
  }
  template <int N>
  StepStatus run(std::array<kalman::AxisFilter<N>, kalman::kMaxAxes>& filters) noexcept;
  template <int N>
  void export_axes(const std::array<kalman::AxisFilter<N>, kalman::kMaxAxes>& filters, double* values,
                   double* covariance) const noexcept;
  template <int N>
  void import_axes(std::array<kalman::AxisFilter<N>, kalman::kMaxAxes>& filters, const double* values,
                   const double* covariance, const std::uint8_t* present) noexcept;
  template <int N>
  bool innovation_axes(const std::array<kalman::AxisFilter<N>, kalman::kMaxAxes>& filters, double* residual,
                       double* variance) const noexcept;
  template <int N>
  void describe_axes(const std::array<kalman::AxisFilter<N>, kalman::kMaxAxes>& filters,
                     Json& out) const;

  // Parameters.
  kalman::Motion motion_ = kalman::Motion::constant_acceleration;
  kalman::OutputTiming timing_ = kalman::OutputTiming::predicted;
  bool initialize_from_first_measurement_ = true;
  kalman::InvalidMeasurement invalid_measurement_ = kalman::InvalidMeasurement::fault;
  std::size_t axes_ = 0;
  double period_s_ = 0.0;
  std::vector<double> q_;
  std::vector<double> p0_;
  std::vector<double> r_;  ///< empty when not given
  Elements measurement_elements_;

  // Ports.
  InputPort measurement_;
  InputPort covariance_;
  estimator::AxisOutputs outputs_;

  // State.
  bool use_covariance_input_ = false;
  /// Per axis: the next valid measurement sets the prior position (initialize_from_first_measurement).
  std::array<bool, kalman::kMaxAxes> start_at_measurement_{};
  std::array<double, kalman::kMaxAxes> variance_{};  ///< R of this cycle, per axis
  std::array<bool, kalman::kMaxAxes> valid_{};       ///< measurement and R usable this cycle
  /// The last step updated every axis with a measurement (innovation() is meaningful).
  bool has_innovation_ = false;
  std::array<kalman::AxisFilter<3>, kalman::kMaxAxes> ca_filters_{};
  std::array<kalman::AxisFilter<2>, kalman::kMaxAxes> cv_filters_{};
};

}  // namespace lode::plugins
