// The simulated acquisition chain's arithmetic, shared by io.sim and by code that runs the same
// simulation without the framework (the hand-written kawato_planar benchmark), so that both
// draw the same noise and quantize alike, bit for bit.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace lode::plugins::sim {

/// Standard normal deviates from an mt19937_64 by Box-Muller: deterministic on every standard
/// library, unlike std::normal_distribution. Draws come in pairs; the second is kept for the
/// next call.
class GaussianNoise {
 public:
  void seed(std::uint64_t seed) noexcept {
    rng_.seed(seed);
    has_spare_ = false;
    spare_ = 0.0;
  }

  double operator()() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    // 53-bit uniforms; u1 in (0, 1] so the logarithm is finite.
    constexpr double kScale = 1.0 / 9007199254740992.0;  // 2^-53
    const double u1 = static_cast<double>((rng_() >> 11) + 1) * kScale;
    const double u2 = static_cast<double>(rng_() >> 11) * kScale;
    const double radius = std::sqrt(-2.0 * std::log(u1));
    const double angle = 2.0 * std::numbers::pi * u2;
    spare_ = radius * std::sin(angle);
    has_spare_ = true;
    return radius * std::cos(angle);
  }

 private:
  std::mt19937_64 rng_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

/// A bipolar converter: two's-complement codes -2^(b-1) ... 2^(b-1)-1 over +-range_v, read
/// by a mid-tread quantizer. Default-constructed (lsb_v 0) it models no converter.
struct ConverterScale {
  double lsb_v = 0.0;  ///< 2 range / 2^bits
  double count_min = 0.0;
  double count_max = 0.0;

  static ConverterScale of(int bits, double range_v) noexcept {
    const double code_count = std::ldexp(1.0, bits);
    return {2.0 * range_v / code_count, -0.5 * code_count, 0.5 * code_count - 1.0};
  }
  [[nodiscard]] bool quantizes() const noexcept { return lsb_v > 0.0; }
  /// The code of `volts`, clipped to [count_min, count_max]; `saturated` tells whether it was.
  double code(double volts, bool& saturated) const noexcept {
    double c = std::floor(volts / lsb_v + 0.5);
    saturated = false;
    if (c > count_max) {
      c = count_max;
      saturated = true;
    } else if (c < count_min) {
      c = count_min;
      saturated = true;
    }
    return c;
  }
};

}  // namespace lode::plugins::sim
