// sensor.laser_gap: laser distance sensors looking at the platen, for its vertical pose.
//
// Silva-Rivas & Kim (2013) measure z, theta (about x) and psi (about y) with three NanoGage
// laser distance sensors; the paper gives neither their geometry, range nor noise, so the spot
// positions and the sensitivity are parameters (geometry supplied by configuration).
//
// Sensor i sees the vertical displacement of the platen point at body coordinates
// (x_i, y_i, 0) under the rotation R = Rx(theta_x) Ry(theta_y) and the lift z:
//   d_i = z + y_i sin(theta_x) - x_i cos(theta_x) sin(theta_y)
//   v_i = offset_v_i + sensitivity_v_per_m * d_i                     [V]
// (small angles: d_i = z + y_i theta_x - x_i theta_y). The Jacobian is analytic.
//
// @sensor
// state:                  # what the model depends on
//   - z: m
//   - theta_x: rad
//   - theta_y: rad
// channels:               # one per sensor, in the order of `sensors`
//   - <sensor name>: V
// @endsensor
//
// Threads: configure()/describe() on the loader thread; evaluate()/jacobian() on the RT
// thread (no allocation, no throw, no I/O).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// One laser spot; the YAML keys of a `sensors` entry have the same names.
struct LaserSpot {
  std::string name;
  double x_m = 0.0;       ///< body-frame position of the spot relative to the centre of mass
  double y_m = 0.0;
  double offset_v = 0.0;  ///< output at zero displacement (the stand-off's voltage)
};

class LaserGap final : public MeasurementModel {
 public:
  static constexpr std::size_t kStateSize = 3;
  static constexpr std::size_t kMaxSensors = 8;
  enum StateIndex : std::size_t { kZ = 0, kThetaX, kThetaY };

  LaserGap();

  Status configure(Params& params) override;
  /// Use these spots and sensitivity (already valid); configure() ends here.
  void apply(std::vector<LaserSpot> spots, double sensitivity_v_per_m);

  void evaluate(const double* state, double* y) const noexcept override;
  void jacobian(const double* state, double* y, double* H) const noexcept override;
  void describe(Json& out) const override;

  [[nodiscard]] double sensitivity_v_per_m() const { return sensitivity_v_per_m_; }
  /// Position noise std [m, rad, rad] of the least-squares pose for a white voltage noise
  /// sigma on every channel: sqrt(diag((H'H)^-1)) sigma at the zero pose.
  [[nodiscard]] std::vector<double> pose_noise_per_volt() const;

 private:
  std::vector<LaserSpot> spots_;
  double sensitivity_v_per_m_ = 1.0;
};

}  // namespace lode::plugins
