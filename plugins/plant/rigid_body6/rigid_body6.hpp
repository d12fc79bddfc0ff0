// plant.rigid_body6: a free 6-DOF rigid body, the magnetically suspended stage of Gutierrez &
// Li 2024 (Newton-Euler model of Eq. 9-10 and Appendix A).
//
// Body frame {B} at the centre of gravity, principal axes (products of inertia ~ 0, Table 1):
//   M dV_B/dt + C(V_B) V_B = F + G_B(Theta)                       (Eq. 9)
//   dP/dt = J(Theta) V_B,   J = blockdiag(R_BF, E)                 (Eq. 10)
// with V_B = [u v w p q r] (body velocities), P = [x y z phi theta psi] (fixed frame,
// z-y-x Euler angles: yaw psi, then pitch theta, then roll phi), M = diag(m, m, m, Ix, Iy, Iz),
// C(V) V = [m Omega x v ; Omega x (I Omega)] (Coriolis and gyroscopic, skew-symmetric C),
// gravity G_B = m R_BF^T [0 0 -g] (z up, assumed; g = gravity_m_s2, default 0 because the
// permanent magnets of the hybrid actuators carry the weight and F is the coil force).
//
// @plant
// inputs:            # body-frame coil force and torque, held constant over each advance() (ZOH)
//   - fx: N, fy: N, fz: N, tx: N*m, ty: N*m, tz: N*m
// outputs:           # what the sensors see: the pose, and the applied force (coil-current readback)
//   - x: m, y: m, z: m, phi: rad, theta: rad, psi: rad
//   - fx: N, fy: N, fz: N, tx: N*m, ty: N*m, tz: N*m   # the input held over the last advance()
// state:
//   - x: m, y: m, z: m, phi: rad, theta: rad, psi: rad, u: m/s, v: m/s, w: m/s, p: rad/s, q: rad/s, r: rad/s
// process model (the estimator's f, same integrator): state = the 12 states above, inputs = fx ... tz
// @endplant
//
// Integration: classical fourth-order Runge-Kutta, `substeps` steps per advance(), the input held.
// For a constant force and no rotation RK4 is exact (the trajectory is a quadratic in t). The
// PlantModel (simulator truth) and the ProcessModel (an estimator's x_{k+1} = f(x_k, u_k)) run the
// same code, so an estimator with the true force reproduces the simulated motion bit for bit.
//
// Threads: configure()/apply()/describe() on the loader thread; reset/advance/output/state/
// propagate on the RT thread (no allocation, no throw).
#pragma once

#include <array>
#include <cstddef>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

namespace rigid_body6 {

/// Named indices into the 12-element state.
enum StateIndex : std::size_t {
  kX = 0, kY, kZ, kPhi, kTheta, kPsi,  // pose P, fixed frame
  kU, kV, kW, kP, kQ, kR,              // body velocity V_B
  kStateSize
};
/// Named indices into the input F (body frame).
enum InputIndex : std::size_t { kFx = 0, kFy, kFz, kTx, kTy, kTz, kInputSize };
inline constexpr std::size_t kPoseSize = 6;

using State = std::array<double, kStateSize>;
using Input = std::array<double, kInputSize>;
using Matrix3 = std::array<std::array<double, 3>, 3>;

struct Physics {
  double mass_kg = 0.931;                                     ///< Table 1
  std::array<double, 3> inertia_kg_m2{1.799e-3, 1.834e-3, 3.336e-3};  ///< Ix, Iy, Iz (Table 1, x 10^-3)
  double gravity_m_s2 = 0.0;                                  ///< 0: the magnets carry the weight
};

/// R_BF(phi, theta, psi): body -> fixed frame, z-y-x sequence (Appendix A).
Matrix3 rotation_body_to_fixed(double phi, double theta, double psi) noexcept;
/// E(phi, theta): body rates [p q r] -> Euler-angle rates (Appendix A); singular at cos(theta) = 0.
Matrix3 euler_rate_matrix(double phi, double theta) noexcept;
/// dx/dt of Eq. 9-10 at state x with input u. RT-safe.
void derivative(const Physics& physics, const State& x, const Input& u, State& dxdt) noexcept;
/// One RK4 step of length h with u held.
void rk4_step(const Physics& physics, const State& x, const Input& u, double h, State& x_next) noexcept;
/// `substeps` RK4 steps over dt with u held (what advance() and propagate() both do).
void integrate(const Physics& physics, std::size_t substeps, const State& x, const Input& u, double dt,
               State& x_next) noexcept;

}  // namespace rigid_body6

/// Parameters; the YAML keys have the same names.
struct RigidBody6Config {
  rigid_body6::Physics physics;
  std::array<double, 6> initial{};           ///< x, y, z [m], phi, theta, psi [rad]
  std::array<double, 6> initial_velocity{};  ///< u, v, w [m/s], p, q, r [rad/s] (body frame)
  std::size_t substeps = 1;                  ///< RK4 steps per advance()/propagate()
};

class RigidBody6 final : public PlantModel, public ProcessModel {
 public:
  static constexpr std::size_t kStateSize = rigid_body6::kStateSize;

  RigidBody6();

  /// Shared by both interfaces (same signature): read parameters, then apply().
  Status configure(Params& params) override;
  /// Use these (already valid) parameters and reset. Tests call it directly.
  void apply(const RigidBody6Config& config);
  [[nodiscard]] const RigidBody6Config& config() const { return config_; }

  // PlantModel: the simulator's truth.
  void reset() noexcept override;
  void advance(double dt_s, const double* u) noexcept override;
  void output(double* y) const noexcept override;
  void state(double* x) const noexcept override;
  void describe(Json& out) const override;

  // ProcessModel: the estimator's f (stateless, same integrator as advance()).
  void propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept override;

 private:
  RigidBody6Config config_;
  rigid_body6::State x_{};
  rigid_body6::Input applied_{};  ///< input held over the last advance() (the readback output)
};

}  // namespace lode::plugins
