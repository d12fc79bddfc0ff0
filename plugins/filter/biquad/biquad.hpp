// filter.biquad: a general second-order section per channel, designed (low-pass, high-pass,
// band-pass, notch; RBJ "Audio EQ Cookbook" forms by prewarped Tustin) or given as raw
// coefficients (e.g. the printed eq. 34 of Silva-Rivas & Kim 2013).
//
// @system
// name: filter.biquad
// input_ports:
//   in:  n elements, any names/units
// output_ports:
//   out: n elements, the same names and units
// @endsystem
//
// Analog prototypes with w0 = 2 pi f_hz and quality factor Q (R. Bristow-Johnson, "Cookbook
// formulae for audio EQ biquad filter coefficients"):
//   lowpass   H(s) = w0^2 / (s^2 + (w0/Q) s + w0^2)
//   highpass  H(s) = s^2 / (s^2 + (w0/Q) s + w0^2)
//   bandpass  H(s) = (w0/Q) s / (s^2 + (w0/Q) s + w0^2)          (0 dB at w0)
//   notch     H(s) = (s^2 + w0^2) / (s^2 + (w0/Q) s + w0^2)
// discretised by the bilinear transform prewarped at w0 (lode::math::tustin), which is exactly
// the cookbook's closed form: with w = w0 T and alpha = sin(w)/(2Q), e.g. the low-pass
//   b = [(1 - cos w)/2, 1 - cos w, (1 - cos w)/2] / (1 + alpha),
//   a = [1, -2 cos w / (1 + alpha), (1 - alpha)/(1 + alpha)].
// Or raw coefficients [b0, b1, b2, a1, a2] (a0 = 1). Each channel runs the transposed direct
// form II  y = b0 x + s1,  s1 <- b1 x - a1 y + s2,  s2 <- b2 x - a2 y.
// Channels not listed in `channels` pass through; set_enabled(false) bypasses (out = in) at run
// time while the sections keep running, so re-enabling has no stale-state transient.
//
// Runtime parameter (`lode set`): enabled (every filtered channel), as set_enabled().
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread;
// set_enabled() from any thread (atomic flags); set_tunable() on the RT thread.
#pragma once

#include <atomic>
#include <cmath>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/sdk/math/biquad.hpp"

namespace lode::plugins {

namespace biquad {

enum class Type { lowpass, highpass, bandpass, notch, coefficients };
const char* to_string(Type type);

/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
using Coefficients = lode::math::BiquadCoefficients;

/// Prewarped-Tustin design of a cookbook form at rate_hz (configure time).
Coefficients design(Type type, double f_hz, double q, double rate_hz);

/// One channel's transposed direct form II section (shared with the other filter plugins).
using Section = lode::math::BiquadSection;

struct ChannelDesign {
  bool filtered = false;
  Type type = Type::lowpass;
  double f_hz = 0.0;
  double q = 0.0;
};

}  // namespace biquad

class BiquadFilter final : public Block, public Tunables {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// Enable (filter) or bypass (out = in) every filtered channel. Any thread, RT-safe.
  void set_enabled(bool enabled) noexcept;
  /// The same for one channel (index into the input); false if it is not a filtered channel.
  bool set_enabled(std::size_t channel, bool enabled) noexcept;
  [[nodiscard]] bool enabled(std::size_t channel) const noexcept;

  /// `lode set`: enabled (bool, index 0).
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  double rate_hz_ = 0.0;
  std::size_t channels_ = 0;
  Elements elements_;
  std::vector<biquad::ChannelDesign> designs_;
  std::vector<biquad::Section> sections_;           ///< one per channel, sized in configure()
  std::unique_ptr<std::atomic<bool>[]> enabled_;   ///< one per channel
  std::vector<double> filtered_value_;               ///< this cycle's section outputs

  InputPort in_;
  OutputPort out_;
};

}  // namespace lode::plugins
