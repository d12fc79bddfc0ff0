// sensor.capacitive_gap: capacitive gap probes looking at flat targets on a 6-DOF body
// (Gutierrez & Li 2024: six probes, 500-1500 um range, 1 mm at home, flat targets >= 30 % larger
// than the probe). The paper does not give the probe geometry: the default layout below is an
// assumption, a 3-2-1 arrangement like the actuators (three vertical probes under the stage,
// three horizontal ones on its sides).
//
// @model
// state:    [x m, y m, z m, phi rad, theta rad, psi rad]   # the pose, z-y-x Euler angles (plant.rigid_body6)
// channels: one per probe, named after it [V]               # v_i = sensitivity_v_per_m (g_i - zero_gap_m)
// @endmodel
//
// Probe i is fixed in the stator with measuring axis n_i (a unit vector, fixed frame) and looks at a
// flat target on the body through the body point r_i (body frame = fixed frame at home). Its face is
// at s_i = r_i - g0 n_i (g0 = nominal_gap_m), so the gap at home is g0. With the body at pose
// (p, R = R_BF(phi, theta, psi)) the target plane passes through p + R r_i with normal R n_i, and the
// gap is the distance along n_i from the probe face to that plane:
//   g_i = (p + R r_i - s_i) . (R n_i) / (n_i . R n_i)
// (moving the body along +n_i opens the gap). The Jacobian is analytic (dR/dangle).
//
// Threads: configure()/describe() on the loader thread; evaluate()/jacobian() on the RT thread.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

struct GapProbe {
  std::string name;
  Eigen::Vector3d target_m = Eigen::Vector3d::Zero();  ///< r_i: target point, body frame [m]
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();     ///< n_i: unit measuring axis, fixed frame
};

struct CapacitiveGapConfig {
  std::vector<GapProbe> probes;
  double nominal_gap_m = 1e-3;        ///< g0: the gap at home (the paper's: all gaps 1 mm)
  double zero_gap_m = 1e-3;           ///< gap that reads 0 V (centre of the 500-1500 um range)
  double sensitivity_v_per_m = 2e4;   ///< 10 V over the +-500 um range
};

/// The default (assumed) 3-2-1 layout: z1..z3 under the stage on a 50 mm circle, 10 mm below the
/// centre of gravity; x1, x2 on the -x face 80 mm apart (x and yaw); y1 on the -y face.
std::vector<GapProbe> default_gap_probes();

class CapacitiveGap final : public MeasurementModel {
 public:
  static constexpr std::size_t kStates = 6;
  static constexpr std::size_t kMaxProbes = 16;

  CapacitiveGap();

  Status configure(Params& params) override;
  /// Use this (already valid) configuration. Tests call it directly.
  void apply(const CapacitiveGapConfig& config);
  [[nodiscard]] const CapacitiveGapConfig& config() const { return config_; }

  void evaluate(const double* state, double* y) const noexcept override;
  void jacobian(const double* state, double* y, double* H) const noexcept override;
  void describe(Json& out) const override;

  /// Gap of every probe [m] at this pose (what the volts encode).
  void gaps(const double* state, double* gap_m) const noexcept;

 private:
  CapacitiveGapConfig config_;
  std::vector<Eigen::Vector3d> face_m_;  ///< s_i = r_i - g0 n_i, sized in apply()
};

}  // namespace lode::plugins
