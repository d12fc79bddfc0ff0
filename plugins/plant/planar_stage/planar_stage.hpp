// plant.planar_stage: the planar 3-DOF platen of Kawato's ATP stage on air bearings.
//
// A frictionless rigid body (thesis eq. 4.44-4.47):
//   m x'' = fx,   m y'' = fy,   Iz th'' = tz + yaw_coupling_m * fx + disturbance_torque_n_m
// The two optional terms model what the thesis blames for its unmodelled behaviour: a force
// asymmetry (a single X actuator off the centre of mass, the ~22 rad/s mode) and the torque of
// the hanging cables.
//
// @plant
// inputs:            # actuator commands, held constant over each advance() (ZOH, as a DAC)
//   - fx: N
//   - fy: N
//   - tz: N*m
// outputs:           # the true configuration, what sensors see
//   - x: m
//   - y: m
//   - theta_z: rad
// state:
//   - x: m, y: m, theta_z: rad, vx: m/s, vy: m/s, omega_z: rad/s
// @endplant
//
// Threads: configure()/apply() on the loader thread; reset/advance/output/state on the RT
// thread (no allocation, no throw).
#pragma once

#include <array>
#include <cstddef>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// Physical parameters of the platen; the YAML keys have the same names.
struct PlanarStageConfig {
  double mass_kg = 6.20;          ///< platen, mirrors, coils, cables (thesis eq. 4.44-4.45)
  double inertia_kg_m2 = 0.054;   ///< Iz about the vertical axis (SolidWorks, thesis eq. 4.46-4.47)
  std::array<double, 3> initial{};           ///< x [m], y [m], theta_z [rad]
  std::array<double, 3> initial_velocity{};  ///< vx [m/s], vy [m/s], omega_z [rad/s]
  double yaw_coupling_m = 0.0;          ///< lever arm: fx also produces the moment fx * lever
  double disturbance_torque_n_m = 0.0;  ///< constant yaw torque, e.g. hanging cables
};

class PlanarStage final : public PlantModel {
 public:
  /// Named indices into the state vector.
  enum StateIndex : std::size_t { kX = 0, kY, kThetaZ, kVx, kVy, kOmegaZ, kStateSize };
  enum InputIndex : std::size_t { kFx = 0, kFy, kTz, kInputSize };
  static constexpr std::size_t kOutputSize = 3;

  PlanarStage();

  Status configure(Params& params) override;
  /// Use these (already valid) parameters and reset to their initial condition. configure()
  /// ends here; tests call it directly to exercise the physics without a YAML file.
  void apply(const PlanarStageConfig& config);
  [[nodiscard]] const PlanarStageConfig& config() const { return config_; }

  void reset() noexcept override;
  void advance(double dt_s, const double* u) noexcept override;
  void output(double* y) const noexcept override;
  void state(double* x) const noexcept override;
  void describe(Json& out) const override;

 private:
  PlanarStageConfig config_;
  std::array<double, kStateSize> x_{};
};

}  // namespace lode::plugins
