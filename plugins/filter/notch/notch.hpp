// filter.notch: second-order digital notch per channel, designed from (f_notch, k, zeta, fs) by
// Tustin prewarped at f_notch, or given as raw coefficients (Silva-Rivas & Kim 2013, eqs. 31-34).
//
// @system
// name: filter.notch
// input_ports:
//   in:  n elements, any names/units      # e.g. hall.pose: x [m], y [m], phi [rad]
// output_ports:
//   out: n elements, the same names and units
// @endsystem
//
// Analog forms, w = 2 pi f_notch:
//   eq31  (default, the paper's eq. 31):  H(s) = (k s^2 + w0^2) / (s^2 + 2 zeta w0 s + w0^2),
//         w0 = w sqrt(k) (eq. 33, from the null condition eq. 32: -k w^2 + w0^2 = 0): an exact
//         null at f_notch, DC gain 1, high-frequency gain k (k = 0.1: -20 dB). Its poles sit at
//         w0 (15.8 Hz for 50 Hz, k = 0.1): a low-pass with a null, not a narrow notch.
//   depth (the textbook notch):  H(s) = (s^2 + 2 k zeta w s + w^2) / (s^2 + 2 zeta w s + w^2):
//         gain k at f_notch, 1 at DC and at high frequency, width set by zeta.
// Discretised by the bilinear transform prewarped at w, in closed form (equal to lode::math::tustin
// within 1e-12, tested; closed so that set_tunable() can redesign on the RT thread):
//   s = c (z - 1)/(z + 1), c = w / tan(w T / 2), so H(e^{jwT}) = H(jw) exactly at f_notch.
// For eq31 this gives, in closed form: Kp = c, b0 = b2 = k Kp^2 + w0^2,
// b1 = 2 w0^2 - 2 k Kp^2, a0 = Kp^2 + 2 zeta w0 Kp + w0^2, a1 = 2 w0^2 - 2 Kp^2,
// a2 = Kp^2 - 2 zeta w0 Kp + w0^2, all divided by a0; DC gain exactly 1.
// Or raw coefficients [b0, b1, b2, a1, a2] (a0 = 1), e.g. the printed eq. 34.
// The sections run in the family's filter::BiquadBank, each channel in transposed direct form II
//   y = b0 x + s1,  s1 <- b1 x - a1 y + s2,  s2 <- b2 x - a2 y.
// Channels not listed in `channels` pass through. set_enabled(false) bypasses the filter
// (out = in) at run time; the sections keep filtering in the background so that re-enabling
// continues from a settled state instead of a stale one.
//
// Runtime parameters (`lode set`): enabled, and for a designed notch f_notch_hz, k and zeta
// (every filtered channel). A retune recomputes the coefficients in closed form (no
// allocation) and re-expresses the section's state for them from the last two inputs and
// outputs, i.e. it switches as a direct form I would: the next output is the new difference
// equation applied to the actual signal history, with no state-mismatch transient.
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread;
// set_enabled() from any thread (atomic flags); set_tunable() on the RT thread at a cycle
// boundary.
#pragma once

#include <cstddef>
#include <vector>

#include "bank_filter.hpp"
#include "biquad_bank.hpp"

namespace lode::plugins {

namespace notch {

enum class Form { eq31, depth, coefficients };
const char* to_string(Form form);

/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
using Coefficients = filter::Coefficients;

/// Prewarped-Tustin design of the eq31 or depth form at rate_hz. Closed form, no allocation:
/// used by configure() and by set_tunable() on the RT thread.
Coefficients design(Form form, double f_notch_hz, double k, double zeta, double rate_hz) noexcept;

/// Per filtered channel: what its section was designed from (describe(), set_tunable()).
struct ChannelDesign {
  Form form = Form::eq31;
  double f_notch_hz = 0.0;
  double k = 0.0;
  double zeta = 0.0;
};

}  // namespace notch

// activate(), step() and the bypass (set_enabled()) are the bank's: filter::BankFilter.
class NotchFilter final : public filter::BankFilter {
 public:
  NotchFilter() noexcept : BankFilter("filter.notch", "non-finite notch state") {}

  Status configure(ConfigureContext& ctx) override;
  void describe(Json& out) const override;

  /// `lode set`: enabled (bool, the bank's), and for a designed notch f_notch_hz, k, zeta.
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  enum TunableIndex : std::size_t { kFrequency = kEnabled + 1, kDepth, kDamping };

  bool designed_ = false;  ///< f_notch_hz, k, zeta exist (not raw coefficients)
  std::vector<notch::ChannelDesign> designs_;  ///< one per filtered channel, in input order
};

}  // namespace lode::plugins
