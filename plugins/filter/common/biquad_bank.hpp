// What the per-channel filter plugins (filter.biquad, filter.notch) share: which input elements
// are filtered, one second-order section per filtered channel, the run-time bypass with its
// `enabled` runtime parameter, describe()'s per-channel report, and the parameters they read
// alike (raw coefficients, one value or one per filtered channel, a frequency below Nyquist).
// A plugin designs the sections' coefficients and hands them to the bank, which runs them.
//
// Each section is a lode::math::BiquadSection: H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1
// + a2 z^-2) in transposed direct form II,  y = b0 x + s1,  s1 <- b1 x - a1 y + s2,
// s2 <- b2 x - a2 y. Channels that are not filtered pass through (out = in). set_enabled(false)
// bypasses the filtered ones (out = in) while their sections keep filtering in the background,
// so re-enabling continues from a settled state instead of a stale one.
//
// Threads: configure_channels()/install()/activate()/describe() on the loader thread; step(),
// retune() and set_enabled_tunable() on the RT thread; set_enabled()/enabled()/enabled_value()
// from any thread (atomic flags).
#pragma once

#include <atomic>
#include <complex>
#include <cstddef>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/sdk/math/biquad.hpp"

namespace lode::plugins::filter {

/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
using Coefficients = lode::math::BiquadCoefficients;

/// One number for every filtered channel, or one per filtered channel (`count`); a wrong count
/// fails `key` and gives `count` zeros.
std::vector<double> per_channel(Params& params, std::string_view key, std::vector<double> values, std::size_t count);

/// Raw [b0, b1, b2, a1, a2] (a0 = 1) from the `coefficients` list: 5 for every filtered channel
/// or 5 per filtered channel, each finite with a stable denominator (problems fail
/// `coefficients`). Nothing when the count of numbers is wrong.
std::optional<std::vector<Coefficients>> raw_coefficients(Params& params, std::vector<double> values, std::size_t count);

/// Both roots of z^2 + a1 z + a2 lie inside the unit circle (Jury: |a2| < 1, |a1| < 1 + a2).
bool stable(const Coefficients& c) noexcept;

/// Fails `key` unless 0 < f_hz < rate_hz / 2.
void require_below_nyquist(Params& params, std::string_view key, double f_hz, double rate_hz);

/// 20 log10 |h|, floored at -400 dB so that an exact null stays a number in describe()'s JSON.
double decibels(std::complex<double> h);

class BiquadBank {
 public:
  /// `plugin` names the block in activate()'s error; `state_fault` is step()'s fault reason when
  /// a section's state or output is not finite. Both string literals.
  BiquadBank(const char* plugin, const char* state_fault) noexcept : plugin_(plugin), state_fault_(state_fault) {}

  /// configure(), first: declares the `in` port, whose source's elements name and size the
  /// channels, and reads `channels` (the elements to filter, default all). Returns how many
  /// channels are filtered: the plugin designs that many sections.
  std::size_t configure_channels(ConfigureContext& ctx);
  /// configure(), last: one section per filtered channel (input order) with `coefficients`,
  /// all enabled or all bypassed; declares `out` with the input's elements. The result of
  /// configure().
  Status install(ConfigureContext& ctx, const std::vector<Coefficients>& coefficients, bool enabled);

  /// Checks the bound input's size; resets the sections and the output.
  Status activate();
  /// One cycle: nullptr, or why it faults: "non-finite input" (checked for every channel
  /// before any output is written) or state_fault. RT-safe.
  const char* step() noexcept;

  /// Filtered channel `slot` (0 .. filtered - 1, input order) takes `c` from the next step,
  /// continuing from its signal history (BiquadSection::retune). RT-safe.
  void retune(std::size_t slot, const Coefficients& c) noexcept { sections_[slot].retune(c); }

  /// Enable (filter) or bypass (out = in) every filtered channel. Any thread, RT-safe.
  void set_enabled(bool enabled) noexcept;
  /// The same for one channel (index into the input); false if it is not a filtered channel.
  bool set_enabled(std::size_t channel, bool enabled) noexcept;
  [[nodiscard]] bool enabled(std::size_t channel) const noexcept;

  /// The `enabled` runtime parameter (bool, every filtered channel).
  [[nodiscard]] static Tunable enabled_tunable();
  /// Its value: the first filtered channel's switch (1: filtering, 0: bypassed or none).
  [[nodiscard]] double enabled_value() const noexcept;
  /// Sets it: 0 or 1, anything else is refused with `why`. RT-safe.
  bool set_enabled_tunable(double value, const char*& why) noexcept;

  /// The block's describe(): rate, structure and one entry per channel. For a filtered channel
  /// `design` adds what its section was designed from, after name, filtered and enabled;
  /// `response` adds derived quantities after its coefficients b, a, dc_gain and nyquist_gain.
  void describe(Json& out, const std::function<void(std::size_t slot, Json& channel)>& design,
                const std::function<void(std::size_t slot, const Coefficients& k, Json& channel)>& response) const;

  [[nodiscard]] double rate_hz() const noexcept { return rate_hz_; }

 private:
  static constexpr std::size_t kPassThrough = std::numeric_limits<std::size_t>::max();

  const char* plugin_;
  const char* state_fault_;
  double rate_hz_ = 0.0;
  std::size_t channels_ = 0;
  Elements elements_;
  std::vector<std::size_t> slot_;                        ///< per channel: its section, or kPassThrough
  std::vector<lode::math::BiquadSection> sections_;      ///< one per filtered channel
  std::vector<double> filtered_value_;                   ///< this cycle's section outputs, per section
  std::unique_ptr<std::atomic<bool>[]> enabled_;        ///< per channel; false for pass-through ones

  InputPort in_;
  OutputPort out_;
};

}  // namespace lode::plugins::filter
