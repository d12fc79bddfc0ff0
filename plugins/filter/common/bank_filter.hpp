// The base of the per-channel filter plugins (filter.biquad, filter.notch): a Block that runs
// its sections in a BiquadBank, with the bank's run-time bypass and its `enabled` runtime
// parameter, so that a plugin writes only its design (configure(), describe()) and the
// runtime parameters it adds.
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread;
// set_enabled()/enabled() from any thread (atomic flags); set_tunable() on the RT thread at a
// cycle boundary.
#pragma once

#include <cstddef>
#include <vector>

#include "biquad_bank.hpp"
#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"

namespace lode::plugins::filter {

class BankFilter : public Block, public Tunables {
 public:
  /// Checks the bound input's size; resets the sections and the output.
  Status activate() final { return bank_.activate(); }
  /// One cycle of the bank; a non-finite input or section state is a fault.
  StepStatus step(const Tick& tick) noexcept final;

  /// Enable (filter) or bypass (out = in) every filtered channel, or one channel (false if it
  /// is not filtered): BiquadBank::set_enabled. Any thread, RT-safe.
  void set_enabled(bool enabled) noexcept { bank_.set_enabled(enabled); }
  bool set_enabled(std::size_t channel, bool enabled) noexcept { return bank_.set_enabled(channel, enabled); }
  [[nodiscard]] bool enabled(std::size_t channel) const noexcept { return bank_.enabled(channel); }

  /// `lode set`: enabled (bool, index kEnabled). A plugin with more runtime parameters puts
  /// them after it and hands kEnabled to these.
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 protected:
  static constexpr std::size_t kEnabled = 0;

  /// `plugin` and `state_fault`: see BiquadBank's constructor.
  BankFilter(const char* plugin, const char* state_fault) noexcept : bank_(plugin, state_fault) {}

  BiquadBank bank_;
};

}  // namespace lode::plugins::filter
