// estimator.arctan_encoder: the "standard" (inverse trigonometric) sin/cos decoder, the
// baseline of Zimmerman, Oshman & Brandes 2006 (eqs. 2-3).
//
// Per sample: fine position within a scale period from the two channels, a coarse cycle
// counter that unwraps it into an absolute position, and velocity by backward difference.
//
//   atan2 (eq. 2):          theta = atan2(z1, z2)
//   arcsin_arccos (eq. 3):  theta = arcsin(z1/|z|)   if |z1| <= |z2|   } with the quadrant
//                           theta = arccos(z2/|z|)   if |z2| <  |z1|   } from the signs of
//                                                                      } z1, z2 (not printed)
//   coarse counter:  n += 1 when theta jumps by < -pi, n -= 1 when it jumps by > pi
//   position:        x_k = (n + theta / (2 pi)) pitch
//   velocity:        v_k = (x_k - x_{k-1}) / T   (backward difference: unnamed in the paper, it
//                                                 fits Table 3; 0 at k = 0)
//
// In exact arithmetic eq. 3 with quadrant logic gives the same angle as eq. 2 (both divide
// by |z|), so both methods have the same noise: sigma / V rad per sample, i.e.
// sigma pitch / (2 pi V) = 5.09 nm and sqrt(2) 5.09 nm / T = 144 um/s at Table 1 values.
// Counting is unambiguous while |v| T < pitch / 2 (40 mm/s at 20 kHz, 4 um pitch).
//
// @system
// name: estimator.arctan_encoder
// input_ports:
//   signals: [sin V, cos V]          # the encoder channels, e.g. io.sim signals
// output_ports:
//   estimate:    [x m, v m/s]        # absolute position and backward-difference velocity
//   cycle_count: [count 1]           # the coarse counter n (whole periods, as a double)
// @endsystem
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <cstdint>

#include "lode/sdk/block.hpp"

namespace lode::plugins {

namespace arctan_encoder {

enum class Method { atan2, arcsin_arccos };

/// Angle of (z_sin, z_cos) in (-pi, pi] by eq. 2 or eq. 3 with quadrant logic.
/// Returns false when |z| = 0 or an input is not finite (no angle exists).
bool decode_angle(Method method, double z_sin, double z_cos, double& theta_rad) noexcept;

/// Coarse counter + fine angle -> absolute position, and backward-difference velocity.
class Decoder {
 public:
  void configure(double pitch_m, double period_s, double initial_position_m) noexcept;
  void reset() noexcept;
  /// One sample's angle. The first sample sets the counter so the position is the one
  /// nearest initial_position_m (the homing reference; the paper does not say how the
  /// counter starts).
  void update(double theta_rad) noexcept;

  [[nodiscard]] double position_m() const noexcept { return position_m_; }
  [[nodiscard]] double velocity_m_s() const noexcept { return velocity_m_s_; }
  [[nodiscard]] std::int64_t cycle_count() const noexcept { return cycle_count_; }

 private:
  double pitch_m_ = 4e-6;
  double period_s_ = 5e-5;
  double initial_position_m_ = 0.0;
  bool first_ = true;
  double previous_theta_rad_ = 0.0;
  std::int64_t cycle_count_ = 0;
  double position_m_ = 0.0;
  double velocity_m_s_ = 0.0;
};

}  // namespace arctan_encoder

class ArctanEncoder final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  arctan_encoder::Method method_ = arctan_encoder::Method::atan2;
  double pitch_m_ = 0.0;
  double period_s_ = 0.0;
  double initial_position_m_ = 0.0;
  arctan_encoder::Decoder decoder_;

  InputPort signals_;
  OutputPort estimate_;
  OutputPort cycle_count_;
};

}  // namespace lode::plugins
