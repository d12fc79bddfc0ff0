// One second-order section, shared by the filter plugins (filter.biquad, filter.notch).
//
//   H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)
//
// run in transposed direct form II: y = b0 x + s1, s1 <- b1 x - a1 y + s2, s2 <- b2 x - a2 y.
// The section also remembers its last two inputs and outputs so that retune() can restate
// s1, s2 for new coefficients:
//   s1 = b1 x(n) - a1 y(n) + b2 x(n-1) - a2 y(n-1),   s2 = b2 x(n) - a2 y(n),
// which is exactly the state the new recursion would have after that history (a retune
// while running does not kick the output). step() and retune() are RT-safe.
#pragma once

#include <cmath>
#include <complex>
#include <numbers>

#include "lode/sdk/math/discretize.hpp"

namespace lode::math {

struct BiquadCoefficients {
  double b0 = 1.0, b1 = 0.0, b2 = 0.0, a1 = 0.0, a2 = 0.0;
};

class BiquadSection {
 public:
  void configure(const BiquadCoefficients& c) {
    c_ = c;
    reset();
  }
  void reset() noexcept { s1_ = s2_ = x1_ = x2_ = y1_ = y2_ = 0.0; }
  /// y for input x; returns false (state unchanged) if the result is not finite.
  bool step(double x, double& y) noexcept {
    const double out = c_.b0 * x + s1_;
    const double s1 = c_.b1 * x - c_.a1 * out + s2_;
    const double s2 = c_.b2 * x - c_.a2 * out;
    if (!std::isfinite(out) || !std::isfinite(s1) || !std::isfinite(s2)) return false;
    s1_ = s1;
    s2_ = s2;
    x2_ = x1_;
    x1_ = x;
    y2_ = y1_;
    y1_ = out;
    y = out;
    return true;
  }
  /// New coefficients from the next step(), continuing from the actual signal history.
  void retune(const BiquadCoefficients& c) noexcept {
    c_ = c;
    s1_ = c.b1 * x1_ - c.a1 * y1_ + c.b2 * x2_ - c.a2 * y2_;
    s2_ = c.b2 * x1_ - c.a2 * y1_;
  }
  [[nodiscard]] const BiquadCoefficients& coefficients() const noexcept { return c_; }

 private:
  BiquadCoefficients c_;
  double s1_ = 0.0, s2_ = 0.0;
  double x1_ = 0.0, x2_ = 0.0;  ///< x(n), x(n-1) after the last step
  double y1_ = 0.0, y2_ = 0.0;  ///< y(n), y(n-1)
};

/// H(e^{j 2 pi f / rate}) of a section (configure time / describe()).
inline std::complex<double> biquad_response(const BiquadCoefficients& c, double f_hz, double rate_hz) {
  return discrete_response({{c.b0, c.b1, c.b2}, {1.0, c.a1, c.a2}}, 2.0 * std::numbers::pi * f_hz, 1.0 / rate_hz);
}

}  // namespace lode::math
