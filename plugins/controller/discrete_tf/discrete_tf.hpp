// controller.discrete_tf: per-axis SISO discrete transfer functions u = D(z) e,
// e = reference - measurement (Kawato 2005, eq. 4.48-4.51 and 5.4).
//
// @system
// name: controller.discrete_tf
// input_ports:
//   measurement: n elements, any names/units                       # e.g. x [m], y [m], theta_z [rad]
//   reference:   n elements, optional, units == measurement units  # 0 when not connected
// output_ports:
//   out: n elements named output_names (default u_<measurement name>) with output_units
// @endsystem
//
// Each axis is either D(s) = K prod(s - z_i) / prod(s - p_j) (real zeros/poles in rad/s)
// discretised at the block's rate by the shared lode::math::matched_pole_zero / lode::math::tustin
// (core/src/math), or D(z) = num(z)/den(z) given directly (descending powers).
//   matched pole-zero: z = e^{sT} for every zero and pole; the n - m zeros at s = infinity go
//     to z = -1 (Franklin, Powell & Workman, Digital Control §6.3.3); with k = (poles at s = 0)
//     - (zeros at s = 0) the gain matches lim s^k D(s) = lim ((z-1)/T)^k D(z) (k = 0: DC gain;
//     k = 1: velocity constant, which gives 2.211e5 for eq. 4.48 against the printed 2.236e5).
//   tustin: s = c (z-1)/(z+1), c = 2/T, or c = w/tan(wT/2) with w = 2 pi prewarp_hz, so that
//     D(e^{jwT}) = D(jw) exactly at the prewarp frequency.
// The difference equation is the transposed direct form II of the monic-denominator D(z):
//   u_k = b0 e_k + s0;  s_i <- b_{i+1} e_k - a_{i+1} u_k + s_{i+1}   (s_n = 0)
// i.e. u_k = -a1 u_{k-1} - ... + b0 e_k + b1 e_{k-1} + ...; for eq. 4.49 at 800 Hz:
//   u_k = 1.2423 u_{k-1} - 0.2423 u_{k-2} + 2.236e5 (e_k - 1.9773 e_{k-1} + 0.977428 e_{k-2}).
// Output limit and anti-windup: when |u| exceeds output_limit the output is clamped, and the
// internal state is not updated if that update would push the next output further in the
// direction of saturation (conditional integration), so an integrator cannot wind up.
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/math/discretize.hpp"

namespace lode::plugins {

namespace discrete_tf {

inline constexpr std::size_t kMaxOrder = 8;

enum class Method { matched, tustin, direct };
const char* to_string(Method method);

/// One axis's discretised controller (off the RT thread).
struct Design {
  Method method = Method::direct;
  // The s-domain form (empty for Method::direct).
  std::vector<double> zeros_s;
  std::vector<double> poles_s;
  double gain_s = 0.0;
  double prewarp_hz = 0.0;  ///< tustin only; 0: no prewarp (c = 2/T)
  /// Matched: the k of the gain matching and lim s^k D(s) (DC gain for k = 0).
  int origin_order = 0;
  double low_frequency_gain = 0.0;

  /// D(z) = num(z)/den(z), descending powers, den[0] = 1, num.size() == den.size() == order + 1.
  std::vector<double> num;
  std::vector<double> den;

  [[nodiscard]] std::size_t order() const { return den.empty() ? 0 : den.size() - 1; }
  /// K of K (z^m + b1 z^{m-1} + ...)/(z^n + a1 z^{n-1} + ...): the first nonzero num coefficient.
  [[nodiscard]] double gain_z() const;
  /// num / gain_z() without its leading zeros: the monic numerator of the thesis's form.
  [[nodiscard]] std::vector<double> monic_numerator() const;
  /// D(z) at a complex z.
  [[nodiscard]] std::complex<double> evaluate(std::complex<double> z) const;
};

/// Roots of a polynomial in descending powers (leading zeros ignored), via the companion matrix.
using lode::math::poly_roots;

/// lode::math::matched_pole_zero with this block's checks and bookkeeping for describe().
Expected<Design> matched_pole_zero(const std::vector<double>& zeros_s, const std::vector<double>& poles_s,
                                   double gain, double period_s);
/// lode::math::tustin (root by root); prewarp_hz = 0: plain Tustin (c = 2/T).
Expected<Design> tustin(const std::vector<double>& zeros_s, const std::vector<double>& poles_s,
                        double gain, double period_s, double prewarp_hz);
Expected<Design> direct(const std::vector<double>& num_z, const std::vector<double>& den_z);

/// The real-time part of one axis: transposed direct form II with clamp and anti-windup.
class Section {
 public:
  /// limit <= 0: no clamp.
  void configure(const Design& design, double limit);
  void reset() noexcept { state_.fill(0.0); }
  /// u = D(z) e for this sample. Returns false (state unchanged) if e or u is not finite.
  bool step(double error, double& output) noexcept;
  [[nodiscard]] bool saturated() const noexcept { return saturated_; }

 private:
  std::size_t order_ = 0;
  double limit_ = 0.0;
  bool saturated_ = false;
  std::array<double, kMaxOrder + 1> b_{};  ///< numerator, descending powers, normalised by den[0]
  std::array<double, kMaxOrder + 1> a_{};  ///< denominator, a_[0] = 1
  std::array<double, kMaxOrder> state_{};
};

}  // namespace discrete_tf

class DiscreteTfController final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  std::size_t axes_ = 0;
  double period_s_ = 0.0;
  std::vector<discrete_tf::Design> designs_;
  std::vector<double> limits_;
  Elements measurement_elements_;  ///< empty if the source was not known at configure time
  Elements output_elements_;

  InputPort measurement_;
  InputPort reference_;
  OutputPort out_;

  std::vector<discrete_tf::Section> sections_;  ///< sized in configure()
  std::vector<double> error_;                   ///< this cycle's e, sized in configure()
};

}  // namespace lode::plugins
