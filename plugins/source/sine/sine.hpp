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

#include "element_source.hpp"
#include "source_elements.hpp"

namespace lode::plugins {

class SineSource final : public source::ElementSource {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// `lode set`: offset.<element>, amplitude.<element>, frequency_hz.<element> (0 ... rate/2).
  /// A new frequency continues from the phase of the last sample (no phase jump).
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  enum TunableGroup : std::size_t { kOffset = source::SourceOutput::kOffsetGroup, kAmplitude, kFrequency };

  double nyquist_hz_ = 0.0;
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
