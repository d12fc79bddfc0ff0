// plant.encoder_stage: a stage axis that moves along a prescribed trajectory, the "signal
// generator" of Zimmerman, Oshman & Brandes 2006 (Fig. 2).
//
// The paper's simulation is open loop: a signal generator produces the true position x(t),
// an encoder turns it into sin/cos, a sampler adds noise and quantises, and the decoders are
// compared with the truth. The test inputs are sinusoids x = A sin(2 pi f t) and a constant
// velocity ramp (Tables 2-4). This plant produces all of them (and their sums) exactly:
//
//   x(t) = offset_m + velocity_m_s t + amplitude_m sin(2 pi frequency_hz t + phase_rad)
//   v(t) = velocity_m_s + 2 pi f A cos(2 pi f t + phase)
//   a(t) = -(2 pi f)^2 A sin(2 pi f t + phase)
//
// Why a plant with an internal trajectory and no inputs (rather than a source block driving
// a plant through io.sim's command port): io.sim holds its command over a period and shows
// it one sample later (ZOH, as a DAC). A position-following plant would be a staircase with
// no defined velocity, and a force-driven double integrator would only approximate the
// sinusoid and need its initial velocity matched. The paper compares both decoders with the
// true position *and velocity* at each sampling instant, so the truth must be the analytic
// x(t_k), v(t_k); the trajectory is the experiment's parameter, not a control input.
//
// @plant
// inputs: []             # none: the motion is prescribed
// outputs:               # the truth the decoders are compared with
//   - x: m
//   - v: m/s
// state:
//   - x: m, v: m/s, a: m/s^2
// @endplant
//
// Threads: configure()/apply()/describe() on the loader thread; reset/advance/output/state
// on the RT thread (no allocation, no throw).
#pragma once

#include <array>
#include <cstddef>

#include "lode/sdk/model.hpp"

namespace lode::plugins {

/// The trajectory; the YAML keys have the same names.
struct EncoderStageConfig {
  double offset_m = 0.0;      ///< position at t = 0 without the sinusoid
  double velocity_m_s = 0.0;  ///< constant velocity (the paper's ramp: 2 mm/s)
  double amplitude_m = 0.0;   ///< sinusoid amplitude A (the paper: 0.1 ... 2 um)
  double frequency_hz = 0.0;  ///< sinusoid frequency f (the paper: 2, 5, 10 Hz)
  double phase_rad = 0.0;     ///< sinusoid phase at t = 0 (not stated in the paper; 0)
};

class EncoderStage final : public PlantModel {
 public:
  enum StateIndex : std::size_t { kX = 0, kV, kA, kStateSize };
  static constexpr std::size_t kOutputSize = 2;

  EncoderStage();

  Status configure(Params& params) override;
  /// Use these (already valid) parameters and reset. configure() ends here.
  void apply(const EncoderStageConfig& config);
  [[nodiscard]] const EncoderStageConfig& config() const { return config_; }

  void reset() noexcept override;
  /// Moves time on by dt_s (u is unused: the plant has no inputs).
  void advance(double dt_s, const double* u) noexcept override;
  void output(double* y) const noexcept override;
  void state(double* x) const noexcept override;
  void describe(Json& out) const override;

  /// Time since reset() [s].
  [[nodiscard]] double time_s() const noexcept { return time_s_; }
  /// x, v, a of the trajectory at time t [s] (pure function of the configuration).
  [[nodiscard]] std::array<double, kStateSize> trajectory(double t_s) const noexcept;

 private:
  EncoderStageConfig config_;
  double time_s_ = 0.0;
  double time_compensation_s_ = 0.0;  ///< Kahan compensation of time_s_ (long runs at 100 kHz)
  std::array<double, kStateSize> x_{};
};

}  // namespace lode::plugins
