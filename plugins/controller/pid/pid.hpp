// controller.pid: per-axis discrete PID with output limits and anti-windup, in the recursive
// (velocity) form of the clamped PID of Sensors 2016, 16, 1504 (eq. 35).
//
// @system
// name: controller.pid
// input_ports:
//   measurement: >= n elements; the controlled elements by name     # e.g. ukf.state: gap [m], ...
//   reference:   n elements, optional (0 when unconnected)          # e.g. ref.out: gap [m]
// output_ports:
//   out: n elements named output_names with output_units            # e.g. coil_voltage [V]
// @endsystem
//
// Per axis, with e = r - y (reference minus measurement), eq. 35 read as output clamping:
//   v(k) = -a1 u(k-1) - a2 u(k-2) + b0 e(k) + b1 e(k-1) + b2 e(k-2)
//   u(k) = clamp(v(k), output_min, output_max)        (f1, f2 of eq. 35: the unclamped value,
//                                                      then saturation)
// The recursion remembers the clamped u, so a saturated integrator cannot wind up: while the
// output sits on a limit the stored u does not move past it (the paper's anti-windup).
// The coefficients are given directly (`coefficients`, e.g. eq. 35: numerator [-623.9, 1020,
// -386.8], denominator [1, -1.604, 0.603]) or designed from PID gains:
//   C(z) = kp + ki T/2 (1 + z^-1)/(1 - z^-1) + c (1 - z^-1)/(1 - p z^-1)
//   p = (2 - N T)/(2 + N T),  c = 2 kd N/(2 + N T)     (Tustin of kd N s/(s + N), N [rad/s])
// which is eq. 35's structure: denominator (1 - z^-1)(1 - p z^-1) (eq. 35: p = 0.603, i.e.
// N = 991 rad/s at 2 kHz). Setpoint weights beta (P) and gamma (D) apply the P and D parts to
// beta r - y and gamma r - y (2-DOF PID; 1, 1 is eq. 35's pure-error form): with beta = gamma
// = 0 a reference step moves the output only through the integral, without the derivative kick.
//
// Runtime parameters (`lode set`): kp, ki, kd (designed from gains only) and output_min,
// output_max, for every axis (`kp`) or one (`kp.<axis>`, with more than one axis). A gain
// change is bumpless: the output continues from u(k-1) by the new gains' increments, i.e.
// in positional terms the integrator absorbs the change (I' = u(k-1) - P'(k-1) - D'(k-1)),
// and the derivative filter's state (the filtered derivative, before kd) is kept. In the
// recursion this is one restated history value, u(k-2) (see rebase_for_new_gains()).
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread;
// set_tunable() on the RT thread at a cycle boundary.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"

namespace lode::plugins {

namespace pid {

inline constexpr std::size_t kMaxAxes = 8;

/// One axis's difference equation (off the RT thread it is built; on it, run).
struct Recursion {
  std::array<double, 3> error_numerator{};      ///< b0, b1, b2 on e (for describe)
  std::array<double, 3> reference_numerator{};  ///< on r: beta P + I + gamma D
  std::array<double, 3> measurement_numerator{};///< on y: P + I + D (= error_numerator)
  std::array<double, 2> denominator{};          ///< a1, a2 of 1 + a1 z^-1 + a2 z^-2
};

/// Gains of C(s) = kp + ki/s + kd N s/(s + N), discretised as in the file comment.
struct Gains {
  double kp = 0.0;
  double ki = 0.0;
  double kd = 0.0;
  double derivative_filter_rad_s = 0.0;  ///< N; 0 only when kd = 0
  double setpoint_weight_p = 1.0;
  double setpoint_weight_d = 1.0;
};
Recursion design(const Gains& gains, double period_s) noexcept;

/// The eq. 35 form directly: numerator b0..b2 on e, denominator a0..a2 (a0 normalised to 1).
Recursion from_coefficients(const std::vector<double>& numerator, const std::vector<double>& denominator);

/// Roots of c0 z^2 + c1 z + c2 (or of the linear / constant polynomial when leading terms vanish).
std::vector<std::array<double, 2>> quadratic_roots(double c0, double c1, double c2);

}  // namespace pid

class PidController final : public Block, public Tunables {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// Cycles in which some axis's output was clamped, since activate().
  [[nodiscard]] std::uint64_t saturation_count() const noexcept {
    return saturations_.load(std::memory_order_relaxed);
  }

  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  struct Axis {
    pid::Recursion recursion;
    double output_min = 0.0;
    double output_max = 0.0;
    double initial_output = 0.0;
    // History of the recursion (the clamped outputs, references and measurements).
    double u1 = 0.0, u2 = 0.0, r1 = 0.0, r2 = 0.0, y1 = 0.0, y2 = 0.0;
    bool clamped = false;  ///< u1 was limited (u1 - u2 is then not the PID's own increment)
  };

  /// Tunable parameters in index order; each has an all-axes entry and, with more than one
  /// axis, one entry per axis after it.
  enum class Knob : std::size_t { kp, ki, kd, output_min, output_max };
  [[nodiscard]] std::size_t knob_stride() const noexcept { return axes_ > 1 ? axes_ + 1 : 1; }
  [[nodiscard]] std::size_t first_knob() const noexcept { return from_gains_ ? 0 : 3; }
  /// Which knob and axes an index names; false if none.
  bool locate(std::size_t index, Knob& knob, std::size_t& first_axis, std::size_t& end_axis) const noexcept;
  /// Restate u(k-2) of axis k so that the recursion with `next` gains continues bumplessly.
  void rebase_for_new_gains(std::size_t k, const pid::Gains& next) noexcept;

  std::size_t axes_ = 0;
  double period_s_ = 0.0;
  bool from_gains_ = true;
  std::vector<pid::Gains> gains_;
  Elements controlled_;
  Elements outputs_;
  std::array<Axis, pid::kMaxAxes> axis_{};
  std::array<std::size_t, pid::kMaxAxes> measurement_index_{};
  std::array<std::size_t, pid::kMaxAxes> reference_index_{};
  bool first_ = true;

  InputPort measurement_;
  InputPort reference_;
  OutputPort out_;

  std::atomic<std::uint64_t> saturations_{0};
};

}  // namespace lode::plugins
