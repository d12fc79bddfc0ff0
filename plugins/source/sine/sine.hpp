// source.sine: sinusoidal reference per element (frequency responses, tracking tests).
//
// @system
// name: source.sine
// output_ports:
//   out: [names...] with [units...]
// @endsystem
//
// With tau = t - start_s (t: scheduled time of the cycle):
//   out(t) = offset                                                  for tau < 0
//          = offset + amplitude * sin(2 pi frequency_hz tau + phase_rad)   for tau >= 0
//
// Threads: configure()/activate() on the loader thread, step() on the RT thread;
// set_tunable() on the RT thread at a cycle boundary.
#pragma once

#include <cstdint>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "../common/source_elements.hpp"

namespace lode::plugins {

class SineSource final : public Block, public Tunables {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// `lode set`: offset.<element>, amplitude.<element>, frequency_hz.<element> (0 ... rate/2).
  /// A new frequency continues from the phase of the last sample (no phase jump).
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  OutputPort out_;
  std::size_t size_ = 0;
  double nyquist_hz_ = 0.0;
  Elements elements_;
  source::ElementTunables tunables_;
  std::vector<double> offset_;
  std::vector<double> amplitude_;
  std::vector<double> frequency_hz_;
  std::vector<double> phase_rad_;
  std::int64_t start_ns_ = 0;
  // Per element, the phase in cycles is  cycles_at_origin + frequency * (tau - origin): a
  // frequency change moves the origin to the last sample and keeps its phase (both 0 until
  // a frequency change, which is the configured sine exactly).
  std::vector<std::int64_t> phase_origin_ns_;
  std::vector<double> cycles_at_origin_;  ///< in [0, 1)
  std::int64_t last_tau_ns_ = 0;          ///< tau of the last step(), 0 before the start
};

}  // namespace lode::plugins
