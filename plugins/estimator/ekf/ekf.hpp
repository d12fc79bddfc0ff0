// estimator.ekf: extended Kalman filter over a plugin process model and a plugin measurement
// model, additive noise (the comparator of Sensors 2016, 16, 1504, Fig. 19).
//
// @system
// name: estimator.ekf
// input_ports:
//   measurement: >= m elements; the measurement model's channels by name  # e.g. hall_direct.gap: gap [m]
//   input:       >= nu elements; the process inputs by name (u_{k-1})      # e.g. stage.truth: coil_voltage [V]
// output_ports:
//   state:      n, the process state elements       # x_{k|k}
//   std:        n, same names and units              # sqrt(diag P_{k|k})
//   innovation: m, the measurement channels          # y_k - h(x_{k|k-1})
// @endsystem
//
// Time update:         x^- = f(x, u_{k-1}),   P^- = F P F' + Q_k,   F = df/dx at (x, u_{k-1})
// Measurement update:  S = H P^- H' + R,  K = P^- H' S^-1,  x = x^- + K (y - h(x^-)),
//                      one channel: P = P^- - K H P^-, its upper triangle mirrored
//                      (symmetric; positive definite as S > 0); more channels:
//                      P = (I - K H) P^- (I - K H)' + K R K'   (Joseph form: symmetric and
//                      positive semidefinite for any gain, under rounding)
// F is the process model's analytic Jacobian when it has one (plant.suspension with the Euler
// step: derived from eq. 33 with the mass divided out), else central differences (jacobian:
// numerical forces them);
// H comes from the measurement model's jacobian(), its columns mapped onto the process state.
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread
// (fixed-capacity Eigen storage: no allocation).
#pragma once

#include "estimator/model_estimator.hpp"

namespace lode::plugins {

class ExtendedEstimator final : public nonlinear::ModelEstimator {
 public:
  enum class JacobianSource { automatic, analytic, numerical };

  /// Whether the last prediction used the model's analytic Jacobian.
  [[nodiscard]] bool used_analytic_jacobian() const { return used_analytic_; }
  [[nodiscard]] const nonlinear::GainMatrix& gain() const { return gain_; }
  /// Whether configure() chose the algebra sized at compile time for the model's (n, m).
  [[nodiscard]] bool fixed_size() const { return fixed_; }

 protected:
  void read_filter_params(Params& params) override;
  Status prepare_filter(Params& params) override;
  StepStatus filter_cycle(bool first) noexcept override;
  void describe_filter(Json& out) const override;

 private:
  /// One cycle in Eigen storage of States x Channels (Eigen::Dynamic: any size up to the
  /// capacity). Fixed sizes take Eigen's small-matrix code; both run the same operations.
  /// FirstStateOnly: h depends on the first process state alone (H = [h 0 ... 0]), so the
  /// products with H and I - K H leave out their exact zero terms.
  template <int States, int Channels, bool FirstStateOnly>
  StepStatus cycle(bool first) noexcept;

  // The sizes of the shipped models (plant.suspension with one gap channel) have their own
  // instance of cycle(); any other (n, m) runs the dynamic one.
  bool fixed_ = false;
  bool measures_first_state_only_ = false;
  Eigen::Matrix3d q_sized_ = Eigen::Matrix3d::Zero();                ///< Q_k (sized cycle)
  Eigen::Matrix<double, 1, 1> r_sized_ = Eigen::Matrix<double, 1, 1>::Zero();  ///< R (sized cycle)
  bool compile_time_sizes_ = true;
  JacobianSource jacobian_ = JacobianSource::automatic;
  bool model_has_jacobian_ = false;
  bool used_analytic_ = false;
  nonlinear::GainMatrix gain_;
};

}  // namespace lode::plugins
