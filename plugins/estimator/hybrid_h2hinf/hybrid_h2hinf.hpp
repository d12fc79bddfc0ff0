// estimator.hybrid_h2hinf: the discrete hybrid H2/H-infinity filter of Silva-Rivas & Kim
// (2013, eqs. 20-30): one constant-acceleration filter per axis whose
// steady-state gain blends a Kalman (H2) gain and a minimax (H-infinity) gain,
//   K = d K_ss^K + (1 - d) K_ss^inf,   0 <= d <= 1                        (eq. 25)
// with d settable at run time (set_mixing). d = 1 is the Kalman filter exactly.
//
// @system
// name: estimator.hybrid_h2hinf
// input_ports:
//   measurement: n elements (n <= 6), any names and units  # e.g. [x, y, theta_z, z, theta_x, theta_y]
// output_ports:
//   pose:         n, same names and units as the measurement  # H x^+_k (or H x^-_{k+1}, output: predicted)
//   velocity:     n, <name>_dot  [<unit>/s]
//   acceleration: n, <name>_ddot [<unit>/s^2]
//   innovation:   n, same names and units                     # y_k - H x^-_k
// @endsystem
//
// Per axis (the 18-state filter of eq. 23 separates into six 3-state filters):
//   x = [p, v, a],  Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],  Upsilon = [T^3/6, T^2/2, T]',
//   H = [1 0 0]                                                           (eq. 20-23)
//   x^-_k = Phi x^+_{k-1},   x^+_k = x^-_k + K (y_k - H x^-_k)          (eq. 24)
// Kalman gain: P = Phi P Phi' - Phi P H'(H P H' + r)^-1 H P Phi' + Upsilon q Upsilon',
//   K^K = P H' (H P H' + r)^-1   (lode::math::steady_state_kalman; eq. 26-28).
// H-infinity gain (the standard form of the paper's cited source, Simon 2001: the paper's own
// eq. 30 was not available here), with performance level theta, error weight S,
// process weight W = Upsilon w Upsilon' and measurement weight V = v:
//   L = (I - theta S P + H' V^-1 H P)^-1,  K^inf = P L H' V^-1,  P <- Phi P L Phi' + W
// iterated to steady state from the Kalman P; feasible only while
//   P^-1 - theta S + H' V^-1 H > 0  at every iteration                    (existence condition)
// An infeasible theta is refused in configure() with the largest feasible theta of that axis.
// The blend is checked like the paper asks: rho((I - K H) Phi) < 1 for the configured d and
// for every d given to set_mixing() (a convex combination of two stable filters need not be
// stable).
//
// invalid_measurement: predict makes an axis with a non-finite measurement coast on the time
// update x^-_{k+1} = Phi x^-_k for that cycle instead of faulting.
//
// Worked example, 800 Hz, r = 1e-6 m^2 (eq. 26), q = 1e3 m^2/s^6 (eq. 27, x):
//   K^K = [0.0760, 2.403 1/s, 38.00 1/s^2], rho = 0.9804 (an independent DARE agrees);
//   theta = 5e5 1/m^2, S = diag(1, 0, 0): K^inf = [0.1360, 3.832 1/s, 53.97 1/s^2], rho = 0.9799.
//
// Threads: configure()/activate()/describe() on the loader thread; step() on the RT thread;
// set_mixing() on any non-RT thread while step() runs (d is an atomic, read once per cycle).
#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "estimator/linear_axes.hpp"
#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/tunables.hpp"

namespace lode::plugins {

namespace hybrid {

using estimator::kAcceleration;
using estimator::kMaxAxes;
using estimator::kPosition;
using estimator::kVelocity;

using Matrix3 = Eigen::Matrix3d;
using Vector3 = Eigen::Vector3d;

/// Phi and Upsilon of eq. 23 for one axis (MotionModel<3>::make(t_s)).
using AxisModel = estimator::MotionModel<3>;

/// Steady-state Kalman (H2) gain of one axis (eqs. 26-28).
struct KalmanDesign {
  bool ok = false;
  std::string error;     ///< why not, when !ok
  Vector3 gain = Vector3::Zero();
  Matrix3 prior_cov = Matrix3::Zero();
};
KalmanDesign design_kalman(const AxisModel& model, double q, double r);

/// Weights of the H-infinity design of one axis (Simon 2001's minimax form).
struct HinfWeights {
  double theta = 0.0;                                ///< performance level (J < 1/theta)
  Vector3 error_weight = Vector3(1.0, 0.0, 0.0);     ///< diagonal of S: [position, velocity, acceleration]
  double process_weight = 0.0;                       ///< w: W = Upsilon w Upsilon'
  double measurement_weight = 0.0;                   ///< v: V = v
};

/// Steady-state H-infinity gain of one axis, or why there is none.
struct HinfDesign {
  enum class Outcome { converged, infeasible, diverged, not_converged, not_finite };
  Outcome outcome = Outcome::not_finite;
  Vector3 gain = Vector3::Zero();
  Matrix3 cov = Matrix3::Zero();  ///< steady P of the H-infinity Riccati recursion
  int iterations = 0;
  /// Smallest eigenvalue of P^{1/2}(P^-1 - theta S + H'V^-1 H)P^{1/2} at the last iteration:
  /// how far from losing definiteness (> 0 feasible).
  double definiteness_margin = 0.0;
  [[nodiscard]] bool ok() const { return outcome == Outcome::converged; }
};

/// Relative change of every gain element between two Riccati iterations that counts as
/// converged, and the iteration budget.
inline constexpr double kRiccatiTolerance = 1e-12;
inline constexpr int kRiccatiMaxIterations = 200'000;

/// Growth of trace(P) over trace(initial P) taken as divergence (theta at or beyond the bound,
/// where the recursion stops contracting; a feasible theta inflates P by far less).
inline constexpr double kDivergenceGrowth = 1e10;

/// Iterates the H-infinity Riccati recursion from `initial_cov` (normally the Kalman P).
HinfDesign design_hinf(const AxisModel& model, const HinfWeights& weights, const Matrix3& initial_cov);

/// Largest theta for which design_hinf() succeeds with these weights (bisection to a relative
/// 1e-6); +inf when every theta up to 1e300 works (e.g. an all-zero error weight).
double max_feasible_theta(const AxisModel& model, HinfWeights weights, const Matrix3& initial_cov);

/// Spectral radius of the filter's error dynamics (I - K H) Phi (eq. 24).
double error_spectral_radius(const AxisModel& model, const Vector3& gain);

/// Closed-loop response measurement -> position estimate of the filter-form recursion:
/// -3 dB bandwidth [Hz] (first crossing below 1/sqrt(2); Nyquist if none) and peak gain [dB].
struct PositionResponse {
  double bandwidth_hz = 0.0;
  double peak_db = 0.0;
  double peak_hz = 0.0;
};
PositionResponse position_response(const AxisModel& model, const Vector3& gain, double t_s);

/// Steady-state a-priori error covariance of the filter x^-_{k+1} = Phi (x^-_k + K (y_k - H x^-_k))
/// run with a fixed gain K on the model it was designed for (jerk variance q, measurement
/// variance r): e^-_{k+1} = Phi (I - K H) e^-_k - Phi K v_k + Upsilon w_k, so P solves the discrete
/// Lyapunov equation
///   P = A P A' + W,   A = Phi (I - K H),   W = Phi K r K' Phi' + Upsilon q Upsilon'
/// (Anderson & Moore, Optimal Filtering, 1979, §4.4 on suboptimal filters; with the
/// Kalman gain it is the DARE's prior covariance). Solved by the squared Smith iteration
/// P_{j+1} = P_j + A_j P_j A_j', A_{j+1} = A_j^2, P_0 = W (Smith 1968, "Matrix equation
/// XA + BX = C", SIAM J. Appl. Math. 16(1)): after j steps P_j sums 2^j terms of the series
/// sum A^k W A'^k, every term symmetric positive semidefinite, so P stays symmetric positive
/// definite under rounding. Fixed-size 3x3 products only: RT-safe (no allocation). False
/// when rho(A) >= 1 makes it diverge or the result is not finite.
bool blended_prior_covariance(const AxisModel& model, const Vector3& gain, double q, double r, Matrix3& cov) noexcept;

/// Per-axis blended gain of eq. 25.
inline Vector3 blend(double d, const Vector3& kalman_gain, const Vector3& hinf_gain) {
  return d * kalman_gain + (1.0 - d) * hinf_gain;
}

using estimator::OutputTiming;
/// A non-finite measurement faults (the default) or makes that axis coast on
/// x^-_{k+1} = Phi x^-_k for the cycle (predict; the step succeeds).
using estimator::InvalidMeasurement;

}  // namespace hybrid

class HybridH2HinfEstimator final : public Block, public Tunables, public EstimatorState {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// Change the mixing weight d of eq. 25 (thread-safe, takes effect at the next cycle).
  /// Refused, leaving d unchanged, if d is outside [0, 1] or the blended filter of any axis
  /// is unstable (rho((I - K H) Phi) >= 1).
  Status set_mixing(double d);
  [[nodiscard]] double mixing() const noexcept { return d_.load(std::memory_order_relaxed); }

  /// `lode set`: d in [0, 1] (index 0). set_tunable() refuses a d whose blend is unstable on
  /// some axis, as set_mixing() does, but RT-safe (fixed-size 3x3 eigenvalues, static reason).
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

  /// @name Estimator state (hot swap). The same layout as estimator.kalman (constant
  /// acceleration): per axis <n> [u], <n>_dot [u/s], <n>_ddot [u/s^2], axis-major, so the two
  /// map 1:1. The state is the prior x^-_k of the coming step; the covariance is the steady
  /// prior covariance of the blended filter at the current d (blended_prior_covariance),
  /// block diagonal: the filter has no P recursion. import_state() takes the state and
  /// ignores the covariance (the gains are steady). innovation(): S(i,i) = P(0,0) + r_i.
  //@{
  [[nodiscard]] StateLayout state_layout() const override;
  void export_state(double* values, double* covariance) const noexcept override;
  void import_state(const double* values, const double* covariance, const std::uint8_t* present) noexcept override;
  [[nodiscard]] std::size_t innovation_size() const override { return axes_; }
  bool innovation(double* residual, double* variance) const noexcept override;
  //@}
  /// Steady prior covariance of axis i at the d of the last step (or the configured d).
  [[nodiscard]] const hybrid::Matrix3& steady_covariance(std::size_t axis) const { return steady_cov_[axis]; }

  /// Designed (or injected) gains of axis i, for tests and describe().
  [[nodiscard]] const hybrid::Vector3& kalman_gain(std::size_t axis) const { return kalman_gain_[axis]; }
  [[nodiscard]] const hybrid::Vector3& hinf_gain(std::size_t axis) const { return hinf_gain_[axis]; }
  [[nodiscard]] std::size_t axes() const { return axes_; }

 private:
  /// Largest rho((I - K(d) H) Phi) over the axes.
  [[nodiscard]] double worst_spectral_radius(double d) const;
  /// steady_cov_ for mixing weight d (RT-safe). False if some axis has no finite solution.
  bool update_steady_covariance(double d) noexcept;

  // Parameters and design.
  hybrid::AxisModel model_;
  hybrid::OutputTiming timing_ = hybrid::OutputTiming::filtered;
  bool initialize_from_first_measurement_ = true;
  hybrid::InvalidMeasurement invalid_measurement_ = hybrid::InvalidMeasurement::fault;
  std::size_t axes_ = 0;
  double period_s_ = 0.0;
  Elements measurement_elements_;
  std::vector<double> q_;
  std::vector<double> r_;
  std::vector<hybrid::HinfWeights> hinf_weights_;  ///< empty when the H-infinity gain is injected
  bool kalman_injected_ = false;
  bool hinf_injected_ = false;
  std::array<hybrid::Vector3, hybrid::kMaxAxes> kalman_gain_{};
  std::array<hybrid::Vector3, hybrid::kMaxAxes> hinf_gain_{};
  std::array<int, hybrid::kMaxAxes> hinf_iterations_{};

  // Run-time mixing weight (eq. 25).
  std::atomic<double> d_{1.0};

  // Ports.
  InputPort measurement_;
  estimator::AxisOutputs outputs_;

  // State: x^-_k per axis (the prior of the coming step; x^+ is formed in step()).
  std::array<hybrid::Vector3, hybrid::kMaxAxes> prior_{};
  /// Per axis: the next valid measurement sets the position (initialize_from_first_measurement).
  std::array<bool, hybrid::kMaxAxes> start_at_measurement_{};
  std::array<double, hybrid::kMaxAxes> last_innovation_{};
  bool has_innovation_ = false;  ///< the last step updated every axis with a measurement

  // Steady prior covariance per axis (RT thread only: updated in step() when d changes).
  std::array<hybrid::Matrix3, hybrid::kMaxAxes> steady_cov_{};
  double steady_cov_d_ = -1.0;  ///< the d steady_cov_ was computed for
};

}  // namespace lode::plugins
