// estimator.glsdc: planar pose from Hall voltages by Gaussian least-squares differential
// correction (Gauss-Newton), as Kawato runs it on the DSP (thesis §4.3, Appendix B/C).
//
// Per tick, warm-started from the previous tick's estimate z (x, y, theta_z), `iterations` times:
//   f = h(z), H = dh/dz(z), dy = y~ - f, J_before = dy' W dy             (W = diag(1/sigma^2))
//   dz = (H' W H)^-1 H' W dy;  z1 = z + dz;  J_after = |y~ - h(z1)|_W^2
//   z = z1 if J_after <= J_before, else z + backoff dz   (thesis scaling factor 0.2; no re-check)
// then at the final z:  R = (H' W H)^-1 (eq. 4.28), cost = |y~ - h(z)|_W^2.
// In 2dof mode theta is fixed (from the `theta` input if connected, else initial[2]) and only
// x, y are estimated with the n x 2 Jacobian (eq. 4.29-4.30).
//
// The measurement model (h and its Jacobian) is a sensor plugin from the pipeline's `models:`,
// e.g. sensor.halbach_hall; its state must be x [m], y [m], theta_z [rad].
//
// @block
// inputs:
//   measurement: <model channels> [V]      # exactly the model's channels, in order
//   theta: [theta_z: rad]                  # 2dof only, optional
// outputs:
//   pose: [x: m, y: m, theta_z: rad]
//   covariance: [xx: m^2, xy: m^2, xth: m*rad, yx: m^2, yy: m^2, yth: m*rad,
//                thx: m*rad, thy: m*rad, thth: rad^2]        # R, row-major; 2dof: theta row/col 0
//   cost: [cost: 1]                                           # J at the published estimate
// @endblock
//
// Sized path: 3dof over a 4-channel model (two two-axis Hall sensors, every shipped
// kawato_planar pipeline) runs storage sized at compile time and reuses work the generic path
// repeats (compile_time_sizes: true, the default): the trial point is evaluated with the
// Jacobian, so an accepted step is already linearised, and R = (H'WH)^-1 is kept for its
// linearisation, so the next tick's first step (same z, same H) does not factor it again.
// Same operations in the same order: the same bits as the generic path, provided the model's
// jacobian() returns the same y as its evaluate() (both are y = h(state)).
//
// Threads: configure()/activate()/describe() on the loader thread; step() on the RT thread
// (no allocation: fixed-capacity Eigen storage sized in configure()).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"

namespace lode::plugins {

class Glsdc final : public Block, public EstimatorState {
 public:
  static constexpr int kMaxChannels = 16;
  static constexpr int kStates = 3;
  enum StateIndex : int { kX = 0, kY, kThetaZ };
  enum class Mode { three_dof, two_dof };
  /// What a non-finite measurement channel (or theta input) does: fault (the default), or
  /// propagate: this cycle's pose, covariance and cost outputs are NaN (a downstream filter
  /// with invalid_measurement: predict then coasts), the warm-start pose is kept, and the
  /// step succeeds.
  enum class InvalidMeasurement { fault, propagate };
  /// Variance exported for a state the solver does not estimate (theta in 2dof) or before the
  /// first solve: (1 m)^2 or (1 rad)^2, i.e. "unknown" at the stage's scale, so that the
  /// exported covariance is positive definite and a filter warm-started from it trusts its
  /// first measurements instead.
  static constexpr double kUnknownVariance = 1.0;

  /// Channel-sized storage with a fixed capacity: resized in configure(), never in step().
  using ChannelVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxChannels, 1>;
  /// Row-major as MeasurementModel::jacobian() writes it.
  using ChannelJacobian =
      Eigen::Matrix<double, Eigen::Dynamic, kStates, Eigen::RowMajor, kMaxChannels, kStates>;
  using State = Eigen::Vector3d;
  using Covariance = Eigen::Matrix3d;
  /// The channel count of the sized path: two two-axis Hall sensors.
  static constexpr int kSizedChannels = 4;
  using SizedVector = Eigen::Matrix<double, kSizedChannels, 1>;
  using SizedJacobian = Eigen::Matrix<double, kSizedChannels, kStates, Eigen::RowMajor>;

  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// @name Estimator state (hot swap). Layout x [m], y [m], theta_z [rad]: the warm-start
  /// pose of the next step, with covariance the last R = (H'WH)^-1 published, symmetrised
  /// (0.5 (R + R'): the published R is the LDLT solve, symmetric only to rounding) (theta row and
  /// column in 2dof, and everything before the first solve: kUnknownVariance on the diagonal,
  /// 0 off it). import_state() sets the warm-start pose (absent elements: `initial`).
  /// GLSDC is a batch solver with no innovation: innovation_size() = 0.
  //@{
  [[nodiscard]] StateLayout state_layout() const override;
  void export_state(double* values, double* covariance) const noexcept override;
  void import_state(const double* values, const double* covariance, const std::uint8_t* present) noexcept override;
  //@}

  /// @name Test hooks (read-only).
  //@{
  [[nodiscard]] const MeasurementModel* model() const noexcept { return model_.get(); }
  /// Ticks whose update was skipped because H'WH was singular (rcond < kMinRcond).
  [[nodiscard]] std::uint64_t singular_skips() const noexcept { return singular_skips_; }
  /// Gauss-Newton steps that were cut to backoff * dz because the cost rose.
  [[nodiscard]] std::uint64_t backoffs() const noexcept { return backoffs_; }
  /// True when step() runs the compile-time-sized path.
  [[nodiscard]] bool fixed_size() const noexcept { return sized_; }
  //@}

  static constexpr double kMinRcond = 1e-12;

 private:
  /// f = h(z) and H = dh/dz at z, reusing the last evaluation when z has not moved (h does not
  /// depend on the measurement, so the previous tick's final evaluation is still valid).
  void linearise(const State& z) noexcept;
  /// Weighted cost |y - f|_W^2.
  [[nodiscard]] double cost_of(const ChannelVector& f) const noexcept;
  /// R = (H' W H)^-1 over the free states and the Gauss-Newton step R H' W (y - f).
  /// Returns false when H' W H is singular (Eigen LDLT rcond estimate < kMinRcond).
  bool solve(Covariance& r, State& dz) const noexcept;
  /// The `iterations` Gauss-Newton steps of one tick; true when H'WH was singular.
  bool iterate() noexcept;
  /// f, H at the published estimate, its cost and R (false: singular, keep the last R).
  bool finish(Covariance& r) noexcept;

  /// @name Sized path (3dof, kSizedChannels channels): the same algebra on fixed-size storage.
  //@{
  bool iterate_sized() noexcept;
  bool finish_sized(Covariance& r) noexcept;
  void linearise_sized(const State& z) noexcept;
  /// solve() over the sized storage, reusing R while the linearisation has not moved.
  bool solve_sized(Covariance& r, State& dz) noexcept;
  //@}
  void publish() noexcept;
  /// invalid_measurement: propagate: NaN on pose, covariance and cost for this cycle.
  void publish_invalid() noexcept;

  // Configuration.
  std::string model_name_;
  ModelPtr<MeasurementModel> model_;
  Mode mode_ = Mode::three_dof;
  InvalidMeasurement invalid_measurement_ = InvalidMeasurement::fault;
  int free_states_ = kStates;
  int channels_ = 0;
  std::int64_t iterations_ = 1;
  double backoff_ = 0.2;
  bool compile_time_sizes_ = true;
  bool sized_ = false;  ///< compile_time_sizes_ and the model fits the sized path
  std::vector<double> noise_std_v_;
  ChannelVector weight_;  ///< W diagonal, 1/sigma^2 [1/V^2]
  State initial_ = State::Zero();

  // Ports.
  InputPort measurement_;
  InputPort theta_;
  OutputPort pose_;
  OutputPort covariance_;
  OutputPort cost_;

  // Estimate and work storage (fixed capacity).
  State z_ = State::Zero();
  Covariance r_ = Covariance::Zero();
  bool has_covariance_ = false;  ///< r_ holds a solved R (false until the first solve)
  double cost_value_ = 0.0;
  ChannelVector measured_;
  ChannelVector predicted_;    ///< h(z) at linearised_at_
  ChannelJacobian jacobian_;   ///< dh/dz at linearised_at_
  ChannelVector trial_;        ///< h(z + dz)
  State linearised_at_ = State::Zero();
  bool linearisation_valid_ = false;

  /// Sized-path storage (kSizedChannels channels, 3 free states).
  struct Sized {
    SizedVector weight = SizedVector::Zero();
    SizedVector measured = SizedVector::Zero();
    SizedVector predicted = SizedVector::Zero();      ///< h(z) at linearised_at_
    SizedJacobian jacobian = SizedJacobian::Zero();   ///< dh/dz at linearised_at_
    SizedVector trial = SizedVector::Zero();          ///< h(z + dz)
    SizedJacobian trial_jacobian = SizedJacobian::Zero();  ///< dh/dz at z + dz
    Covariance factor_r = Covariance::Zero();  ///< (H'WH)^-1 at linearised_at_, when factor_ok
    bool factor_ok = false;     ///< H'WH at linearised_at_ passed the LDLT checks
    bool factor_valid = false;  ///< factor_r / factor_ok belong to the current linearisation
  };
  Sized sized_work_;

  std::uint64_t singular_skips_ = 0;
  bool was_singular_ = false;
  std::string block_name_;  ///< source of rt_log records (lives as long as the block)
  std::uint64_t backoffs_ = 0;
};

}  // namespace lode::plugins
