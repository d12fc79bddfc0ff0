// estimator.gap_pose: the 6-DOF pose from gap-probe voltages (the forward kinematics Gutierrez &
// Li 2024 use but do not give: "the 6-DOF pose is computed from the six gaps").
//
// The probes' model y = h(P) (e.g. sensor.capacitive_gap, geometry from configuration) is inverted
// by weighted Gauss-Newton, warm-started from the previous tick's pose, `iterations` steps per tick:
//   f = h(P), H = dh/dP(P),  dP = (H' W H)^-1 H' W (y - f),  P += dP       (W = diag(1/sigma^2))
// With six probes H is square and the solve is Newton's method on h(P) = y; with more probes it is
// the least-squares pose. Newton converges quadratically from the previous tick's pose: one step
// leaves an error of the order of (motion per tick)^2 (~1e-15 at 11.5 um/s and 200 urad/s), the
// default of two steps reaches rounding, and a few steps cover a cold start far from home.
//
// @block
// inputs:
//   measurement: <model channels> [V]                           # exactly the model's channels, in order
// outputs:
//   pose: [x m, y m, z m, phi rad, theta rad, psi rad]          # the model's state elements
//   cost: [cost 1]                                              # |y - h(P)|_W^2 at the published pose
// @endblock
//
// Threads: configure()/activate()/describe() on the loader thread; step() on the RT thread (no
// allocation: fixed-capacity Eigen storage sized in configure()).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"

namespace lode::plugins {

class GapPose final : public Block {
 public:
  static constexpr int kStates = 6;
  static constexpr int kMaxChannels = 16;

  using Pose = Eigen::Matrix<double, kStates, 1>;
  using ChannelVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxChannels, 1>;
  using ChannelJacobian = Eigen::Matrix<double, Eigen::Dynamic, kStates, Eigen::RowMajor, kMaxChannels, kStates>;
  using Normal = Eigen::Matrix<double, kStates, kStates>;

  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// Smallest reciprocal condition of the column-scaled H'WH accepted at configure time.
  static constexpr double kMinRcond = 1e-12;
  /// Smallest LDLT pivot, relative to the largest, accepted in step().
  static constexpr double kMinPivot = 1e-16;

 private:
  // Parameters.
  std::string model_name_;
  int iterations_ = 2;
  std::vector<double> noise_std_v_;
  Pose initial_ = Pose::Zero();

  ModelPtr<MeasurementModel> model_;
  int channels_ = 0;

  // Ports.
  InputPort measurement_;
  OutputPort pose_;
  OutputPort cost_;

  // State and scratch (capacity fixed, sized in configure()).
  Pose pose_estimate_ = Pose::Zero();
  ChannelVector weight_;
  ChannelVector measured_;
  ChannelVector predicted_;
  ChannelJacobian jacobian_;
};

}  // namespace lode::plugins
