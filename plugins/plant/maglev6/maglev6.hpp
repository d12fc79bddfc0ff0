// plant.maglev6: the six-axis maglev platen of Silva-Rivas & Kim (2013) on air bearings.
//
// Rigid body with decoupled axes (paper eqs. 2-5):
//   M x'' = fx,  M y'' = fy,  Izz tz'' = tz                         planar: pure mass
//   M z'' = fz - Kz z,  Ixx tx'' = tx - Ktx tx,  Iyy ty'' = ty - Kty ty   vertical: air-bearing springs
// The generalised forces come from the motor currents through surrogate input matrices (fitted
// here by inverse LQR to the printed gains, README; the paper gives neither the winding density
// nor the force/torque allocation), plus an optional constant disturbance wrench:
//   [x'' y'' tz'']  = B_planar   [iq_a iq_b iq_c]'   (eq. 11 form, horizontal mode)
//   [z'' tx'' ty''] = B_vertical [id_a id_b id_c]' - diag(Kz/M, Ktx/Ixx, Kty/Iyy) [z tx ty]'
//
// Axis names: the paper's phi, theta, psi are rotations about z, x and y (its eqs. 3, 5), written
// here theta_z, theta_x, theta_y so that no reader has to remember that convention.
//
// @plant
// inputs:                 # motor currents, held constant over each advance() (ZOH, as a DAC)
//   - iq_a: A             # quadrature currents (horizontal force) of motors A, B, C
//   - iq_b: A
//   - iq_c: A
//   - id_a: A             # direct currents (vertical force) of motors A, B, C
//   - id_b: A
//   - id_c: A
// outputs:                # the true pose, the paper's [x y phi z theta psi]
//   - x: m
//   - y: m
//   - theta_z: rad
//   - z: m
//   - theta_x: rad
//   - theta_y: rad
// state:                  # pose, then velocities in the same order
//   - x, y, theta_z, z, theta_x, theta_y, vx, vy, omega_z, vz, omega_x, omega_y
// @endplant
//
// Also a lode::ProcessModel (x_{k+1} = f(x, u), the same exact ZOH physics, stateless), so a
// model-based estimator can share this physics with the simulator.
//
// Threads: configure()/apply()/describe() on the loader thread; reset/advance/output/state and
// propagate/process_jacobian on the RT thread (no allocation, no throw).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// Physical parameters; the YAML keys have the same names.
struct Maglev6Config {
  double mass_kg = 1.52;                       ///< moving mass M (the paper's)
  double inertia_xx_kg_m2 = 0.0037;            ///< principal inertia about x
  double inertia_yy_kg_m2 = 0.0019;            ///< principal inertia about y
  double inertia_zz_kg_m2 = 0.0022;            ///< principal inertia about z
  double stiffness_z_n_per_m = 620.0;          ///< air-bearing stiffness Kz (Hooke's law)
  double stiffness_theta_x_n_m_per_rad = 65.0; ///< torsional stiffness about x (K_theta)
  double stiffness_theta_y_n_m_per_rad = 87.0; ///< torsional stiffness about y (K_psi)
  /// Accelerations per ampere, rows [x'', y'', theta_z''], columns motors A, B, C
  /// (surrogate fitted to eq. 17 at 800 Hz; [m/s^2/A] for x, y and [rad/s^2/A] for theta_z).
  Eigen::Matrix3d b_planar_acc_per_a = (Eigen::Matrix3d() << -0.554, 0.519, 12.903,  //
                                        13.369, 13.55, -0.088,                        //
                                        -209.292, 199.399, -183.1)
                                           .finished();
  /// Rows [z'', theta_x'', theta_y''], columns motors A, B, C (surrogate fitted to eq. 19 at 1 kHz).
  Eigen::Matrix3d b_vertical_acc_per_a = (Eigen::Matrix3d() << 10.571, 10.597, 22.781,  //
                                          -256.201, -256.513, 475.071,                   //
                                          360.858, -343.005, 12.837)
                                             .finished();
  std::array<double, 6> initial{};           ///< x, y, theta_z, z, theta_x, theta_y [m, rad]
  std::array<double, 6> initial_velocity{};  ///< their rates [m/s, rad/s]
  /// Constant disturbance wrench: fx [N], fy [N], tz [N*m], fz [N], tx [N*m], ty [N*m].
  std::array<double, 6> disturbance_wrench{};
};

class Maglev6 final : public PlantModel, public ProcessModel {
 public:
  static constexpr std::size_t kAxes = 6;
  static constexpr std::size_t kStateSize = 12;
  static constexpr std::size_t kInputSize = 6;
  /// Named indices: pose axes; the velocity of axis i is at kAxes + i.
  enum Axis : std::size_t { kX = 0, kY, kThetaZ, kZ, kThetaX, kThetaY };
  enum Input : std::size_t { kIqA = 0, kIqB, kIqC, kIdA, kIdB, kIdC };

  /// Continuous-time state-space model of one mode (eq. 11 form): states [p(3), v(3)],
  /// inputs the three currents of that mode, outputs the three positions.
  struct Mode {
    Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 3> b = Eigen::Matrix<double, 6, 3>::Zero();
    Eigen::Matrix<double, 3, 6> c = Eigen::Matrix<double, 3, 6>::Zero();
  };

  Maglev6();

  Status configure(Params& params) override;  // both PlantModel and ProcessModel
  /// Use these (already valid) parameters and reset; configure() ends here. Tests call it
  /// directly to exercise the physics without a YAML file.
  void apply(const Maglev6Config& config);
  [[nodiscard]] const Maglev6Config& config() const { return config_; }

  // PlantModel
  void reset() noexcept override;
  void advance(double dt_s, const double* u) noexcept override;
  void output(double* y) const noexcept override;
  void state(double* x) const noexcept override;
  void describe(Json& out) const override;

  // ProcessModel
  void propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept override;
  bool process_jacobian(double dt_s, const double* x, const double* u, double* F) const noexcept override;

  /// Horizontal (x, y, theta_z; quadrature currents) and vertical (z, theta_x, theta_y;
  /// direct currents) continuous models, e.g. to design an LQ controller.
  [[nodiscard]] Mode planar_mode() const;
  [[nodiscard]] Mode vertical_mode() const;
  /// Undamped natural frequency of each axis [rad/s]: 0 for the planar axes.
  [[nodiscard]] const std::array<double, kAxes>& natural_frequency_rad_s() const { return omega_; }

 private:
  /// Acceleration of every axis from the currents, excluding the spring term.
  void forcing(const double* u, std::array<double, kAxes>& acceleration) const noexcept;
  /// Exact ZOH step of x'' = -w^2 x + a over dt for every axis.
  void integrate(double dt_s, const double* x, const std::array<double, kAxes>& acceleration,
                 double* x_next) const noexcept;

  Maglev6Config config_;
  std::array<double, kAxes> omega_{};           ///< sqrt(K / M) per axis
  std::array<double, kAxes> inverse_inertia_{}; ///< 1/M or 1/I per axis (for the wrench)
  std::array<double, kStateSize> x_{};
};

}  // namespace lode::plugins
