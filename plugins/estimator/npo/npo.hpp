// estimator.npo: the nonlinear passive observer (NPO) of Gutierrez & Li (2024) for the 6-DOF
// body velocity of a magnetically suspended stage, Eq. 11-14, with an exact discrete update
// (forward Euler is unstable at the paper's gains; the paper does not say how it discretised).
//
// @system
// name: estimator.npo
// input_ports:
//   measurement: [x m, y m, z m, phi rad, theta rad, psi rad]   # Z: the (low-pass filtered) measured pose
//   force: any port holding the model's inputs by name           # F: fx fy fz [N], tx ty tz [N*m], body frame,
//                                                                #    held over the last period (e.g. the
//                                                                #    plant's force readback in board.truth)
// output_ports:
//   velocity:    [u m/s, v m/s, w m/s, p rad/s, q rad/s, r rad/s]  # V^_B, Eq. 12
//   pose:        same names and units as the measurement         # P^, Eq. 14
//   innovation:  same names and units as the measurement         # Z_k - P^_k after the update
//   fd_velocity: [<name>_dot, <unit>/s]                           # (Z_k - Z_{k-1}) / T, the paper's "measured
//                                                                #    velocity" baseline (Figs. 5-10)
//   state:       the process model's state [P^, V^_B] (12)       # same layout as io.sim's plant_state, so a
//                                                                #    monitor can compare estimate and truth
// @endsystem
//
// Continuous observer (Eq. 11-14, with the signs that make Eq. 15-18 follow):
//   M dV^/dt = F - C(V^) V^ + G_B + D0 (Z - P^),   dP^/dt = J(Theta^) V^ + A0 (Z - P^)
// It is the plant (Eq. 9-10) plus an output injection L = [A0; M^-1 D0] of the innovation. The
// plant part is the process model from `models:` (e.g. plant.rigid_body6), so the observer is a
// copy of exactly the physics the simulator runs; C is evaluated at V^ (the paper writes C(V_B)
// of the true velocity, which is not measurable).
//
// Discrete update, every period T with Z_{k+1}, the force F_k held over [t_k, t_{k+1}] and the
// previous posterior residual nu_k = Z_k - P^_k:
//   x^- = f(x^_k, F_k)                                  (process model: the plant over T)
//   nu^- = Z_{k+1} - P^-
//   P^_{k+1} = P^- + g_p nu_k + h_p nu^-,    V^_{k+1} = V^- + g_v nu_k + h_v nu^-      (per axis)
// With a perfect model and noise-free Z the innovations stay 0: the estimate is exact whatever the
// gains (the complementary-filter property, check S1). Per axis (J = I, C = 0) the
// estimation error e = (P - P^, V - V^) then obeys e_{k+1} = E e_k with
//   E = Ad - [g + h, T h],   Ad = [[1, T], [0, 1]]
// and the gains are chosen by `integrator`:
//   exact:          E = exp(A_e T), A_e = [[-a, 1], [-d/m, 0]]: the continuous error dynamics
//                   (Eq. 15-18) sampled exactly: h = (Ad - E).col(1) / T, g = (Ad - E).col(0) - h.
//                   The composite W = 1/2 m v~^2 + 1/2 d p~^2 (a Lyapunov function derived here
//                   to close the paper's passivity argument) is non-increasing.
//   backward_euler: implicit in the stiff A0 term: P^ = (P^- + aT Z)/(1 + aT),
//                   then V^ = V^- + T (d/m) (Z - P^): g = 0, h = [aT, T d/m] / (1 + aT).
//   forward_euler:  explicit injection g = [aT, T d/m], h = 0. At a T = 4 (Table 2) an eigenvalue
//                   sits at 1 - aT = -3: configure() refuses every unstable E with the eigenvalue.
// `dynamics: linear` replaces the process model by six decoupled double integrators (J = I, C = 0)
// with the same M (and the model's force-free acceleration at rest, i.e. gravity if it has any):
// the per-axis linear fallback and the reference of check S7 (tests/integration/seed004_test.cpp).
//
// Gains: d0 [N/m | N*m/rad] and a0_per_s [1/s] per axis (Table 2: d0 = 100, a0 = 1e4 or 1e-4,
// units not stated: README), or a tuning rule derived here: a = 2 zeta w, d = m w^2
// (observer_frequency_hz, observer_damping). M is read off the process model at rest
// (M_i = T / dV_i per unit F_i).
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <Eigen/Core>
#include <array>
#include <complex>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"

namespace lode::plugins {

namespace npo {

inline constexpr std::size_t kAxes = 6;
inline constexpr std::size_t kStates = 12;  ///< [P (6), V_B (6)], the process model's layout

enum class Integrator { exact, backward_euler, forward_euler };
enum class Dynamics { nonlinear, linear };

const char* to_string(Integrator integrator);

/// One axis of the observer: its physics, continuous gains and discrete update gains.
struct AxisDesign {
  double mass = 0.0;       ///< m or I_i [kg | kg*m^2]
  double d = 0.0;          ///< D0 entry [N/m | N*m/rad]
  double a = 0.0;          ///< A0 entry [1/s]
  double period_s = 0.0;
  double g_p = 0.0, g_v = 0.0;  ///< gains on the previous residual nu_k   [1], [1/s]
  double h_p = 0.0, h_v = 0.0;  ///< gains on the a-priori innovation nu^- [1], [1/s]
  /// Error transition e_{k+1} = E e_k, e = (p~, v~).
  Eigen::Matrix2d transition = Eigen::Matrix2d::Identity();
  /// Roots of m s^2 + m a s + d (the per-axis error dynamics) [rad/s] and the eigenvalues of E.
  std::array<std::complex<double>, 2> continuous_poles{};
  std::array<std::complex<double>, 2> discrete_poles{};
  [[nodiscard]] double spectral_radius() const;
};

/// Gains and error transition of one axis for this integrator (off the RT thread).
AxisDesign design_axis(double mass, double d, double a, double period_s, Integrator integrator);

/// Steady estimation error (p~, v~) of the discrete observer for a constant force bias b = 1
/// (the observer is told F + b): e = -(I - E)^-1 (I - h C) Bd. The continuous answer is
/// p~ = -b/d, v~ = -a b/d.
Eigen::Vector2d bias_response(const AxisDesign& axis);

/// True when W = 1/2 m v~^2 + 1/2 d p~^2 cannot grow over one step: E' diag(d, m) E <= diag(d, m).
bool lyapunov_non_increasing(const AxisDesign& axis);

}  // namespace npo

class NonlinearPassiveObserver final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// @name Test hooks (read-only).
  //@{
  [[nodiscard]] const npo::AxisDesign& axis(std::size_t i) const { return axes_[i]; }
  [[nodiscard]] npo::Integrator integrator() const noexcept { return integrator_; }
  [[nodiscard]] npo::Dynamics dynamics() const noexcept { return dynamics_; }
  //@}

 private:
  using State = std::array<double, npo::kStates>;
  using AxisValues = std::array<double, npo::kAxes>;

  /// M from the process model at rest, and the force-free acceleration there (gravity, if any).
  Status identify_mass(Params& params, AxisValues& mass);
  void read_gains(Params& params, const AxisValues& mass, AxisValues& d, AxisValues& a);
  void predict(const AxisValues& force, State& predicted) const noexcept;
  void publish() noexcept;

  // Parameters.
  std::string model_name_;
  npo::Integrator integrator_ = npo::Integrator::exact;
  npo::Dynamics dynamics_ = npo::Dynamics::nonlinear;
  bool initialize_from_first_measurement_ = true;
  State initial_{};
  double period_s_ = 0.0;
  bool gains_from_tuning_ = false;
  AxisValues observer_frequency_hz_{};
  AxisValues observer_damping_{};

  // Model and design.
  ModelPtr<ProcessModel> model_;
  std::array<npo::AxisDesign, npo::kAxes> axes_{};
  std::array<std::size_t, npo::kAxes> force_index_{};  ///< model input i -> element of the force port
  AxisValues rest_acceleration_{};  ///< the model's force-free acceleration at rest (linear dynamics)
  Elements measurement_elements_;
  Elements velocity_elements_;

  // Ports.
  InputPort measurement_;
  InputPort force_;
  OutputPort velocity_;
  OutputPort pose_;
  OutputPort innovation_;
  OutputPort fd_velocity_;
  OutputPort state_;

  // State (the estimate x^_k = [P^, V^_B], the residual nu_k and Z_k).
  State estimate_{};
  AxisValues residual_{};
  AxisValues previous_measurement_{};
  AxisValues fd_{};
  bool first_cycle_ = true;
};

}  // namespace lode::plugins
