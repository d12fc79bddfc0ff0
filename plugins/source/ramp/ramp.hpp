// source.ramp: constant-rate reference, e.g. the thesis's +-theta_z ramps that found the
// rotation range -0.12 ... +0.16 rad (Kawato 2005, Figs. 62-63), and rate-limited large moves.
//
// @system
// name: source.ramp
// output_ports:
//   out: [names...] with [units...]
// @endsystem
//
// With tau = t - start_s (t: scheduled time of the cycle) and D = duration_s (infinite if absent):
//   out(t) = offset                          for tau < 0
//          = offset + rate * tau             for 0 <= tau < D
//          = offset + rate * D               for tau >= D (hold)
//
// Threads: configure()/activate() on the loader thread, step() on the RT thread;
// set_tunable() on the RT thread at a cycle boundary.
#pragma once

#include <cstdint>
#include <vector>

#include "element_source.hpp"
#include "source_elements.hpp"

namespace lode::plugins {

class RampSource final : public source::ElementSource {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// `lode set`: offset.<element> and rate.<element>. A new rate bends the ramp at the last
  /// sample (the output stays continuous; only its slope changes), see rate_origin_ns_.
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

 private:
  enum TunableGroup : std::size_t { kOffset = source::SourceOutput::kOffsetGroup, kRate };

  std::vector<double> rate_;  ///< element unit per second
  std::int64_t start_ns_ = 0;
  bool has_duration_ = false;
  std::int64_t duration_ns_ = 0;
  // Per element, the ramp is  value_at_origin + rate * (ramp time - rate_origin_ns): a rate
  // change moves the origin to the last sample's ramp time and accumulates what the old rate
  // had produced, so the output continues from where it was (both 0 until a rate change).
  std::vector<std::int64_t> rate_origin_ns_;
  std::vector<double> value_at_origin_;
  std::int64_t last_ramp_ns_ = 0;  ///< clamped ramp time of the last step()
};

}  // namespace lode::plugins
