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
// Threads: configure()/activate() on the loader thread, step() on the RT thread.
#pragma once

#include <cstdint>
#include <vector>

#include "lode/block.hpp"

namespace lode::plugins {

class SineSource final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  OutputPort out_;
  std::size_t size_ = 0;
  std::vector<double> offset_;
  std::vector<double> amplitude_;
  std::vector<double> frequency_hz_;
  std::vector<double> phase_rad_;
  std::int64_t start_ns_ = 0;
};

}  // namespace lode::plugins
