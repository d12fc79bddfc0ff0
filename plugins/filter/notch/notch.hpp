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
// Each channel runs the transposed direct form II
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

namespace notch {

enum class Form { eq31, depth, coefficients };
const char* to_string(Form form);

/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
using Coefficients = lode::math::BiquadCoefficients;

/// Prewarped-Tustin design of the eq31 or depth form at rate_hz. Closed form, no allocation:
/// used by configure() and by set_tunable() on the RT thread.
Coefficients design(Form form, double f_notch_hz, double k, double zeta, double rate_hz) noexcept;

/// One channel's second-order section (with retune(): lode::math::BiquadSection).
using Section = lode::math::BiquadSection;

/// Per channel: what it was designed from (for describe()).
struct ChannelDesign {
  bool filtered = false;
  Form form = Form::eq31;
  double f_notch_hz = 0.0;
  double k = 0.0;
  double zeta = 0.0;
};

}  // namespace notch

class NotchFilter final : public Block, public Tunables {
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

  /// `lode set`: enabled (bool), and for a designed notch f_notch_hz, k, zeta.
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  enum TunableIndex : std::size_t { kEnabled = 0, kFrequency = 1, kDepth = 2, kDamping = 3 };
  /// The first filtered channel (whose design tunable_value() reports), channels_ if none.
  [[nodiscard]] std::size_t first_filtered() const noexcept;

  double rate_hz_ = 0.0;
  bool designed_ = false;  ///< f_notch_hz, k, zeta exist (not raw coefficients)
  std::size_t channels_ = 0;
  Elements elements_;
  std::vector<notch::ChannelDesign> designs_;
  std::vector<notch::Section> sections_;               ///< one per channel, sized in configure()
  std::unique_ptr<std::atomic<bool>[]> enabled_;      ///< one per channel
  std::vector<double> filtered_value_;                  ///< this cycle's section outputs

  InputPort in_;
  OutputPort out_;
};

}  // namespace lode::plugins
