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
// Or raw coefficients [b0, b1, b2, a1, a2] (a0 = 1). The sections run in the family's
// filter::BiquadBank (transposed direct form II per channel; channels not listed in `channels`
// pass through; set_enabled(false) bypasses, out = in, at run time while the sections keep
// running, so re-enabling has no stale-state transient).
//
// Runtime parameter (`lode set`): enabled (every filtered channel), as set_enabled().
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread;
// set_enabled() from any thread (atomic flags); set_tunable() on the RT thread.
#pragma once

#include <cstddef>
#include <vector>

#include "bank_filter.hpp"
#include "biquad_bank.hpp"

namespace lode::plugins {

namespace biquad {

enum class Type { lowpass, highpass, bandpass, notch, coefficients };
const char* to_string(Type type);

/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
using Coefficients = filter::Coefficients;

/// Prewarped-Tustin design of a cookbook form at rate_hz (configure time).
Coefficients design(Type type, double f_hz, double q, double rate_hz);

/// Per filtered channel: what its section was designed from (for describe()).
struct ChannelDesign {
  Type type = Type::lowpass;
  double f_hz = 0.0;
  double q = 0.0;
};

}  // namespace biquad

// activate(), step(), the bypass (set_enabled()) and `lode set enabled` are the bank's:
// filter::BankFilter.
class BiquadFilter final : public filter::BankFilter {
 public:
  BiquadFilter() noexcept : BankFilter("filter.biquad", "non-finite biquad state") {}

  Status configure(ConfigureContext& ctx) override;
  void describe(Json& out) const override;

 private:
  std::vector<biquad::ChannelDesign> designs_;  ///< one per filtered channel, in input order
};

}  // namespace lode::plugins
