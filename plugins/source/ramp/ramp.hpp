// source.ramp: constant-rate reference, e.g. the thesis's +-theta_z ramps that found the
// rotation range -0.12 ... +0.16 rad (spec seed-000 §7.3, §9 item 9).
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
// Threads: configure()/activate() on the loader thread, step() on the RT thread.
#pragma once

#include <cstdint>
#include <vector>

#include "lode/block.hpp"

namespace lode::plugins {

class RampSource final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  OutputPort out_;
  std::size_t size_ = 0;
  std::vector<double> offset_;
  std::vector<double> rate_;  ///< element unit per second
  std::int64_t start_ns_ = 0;
  bool has_duration_ = false;
  std::int64_t duration_ns_ = 0;
};

}  // namespace lode::plugins
