// source.zigzag: the zig-zag XY path of the thesis's accuracy experiment (Kawato 2005, Fig. 49:
// the trajectory run against the laser to build the 2-D error table).
//
// @system
// name: source.zigzag
// output_ports:
//   out: [names...] with [units...]
// @endsystem
//
// With tau = t - start_s, half period H = period_s / 2, k = floor(tau / H) (completed half
// periods) and f = tau / H - k in [0, 1):
//   sweep(tau)   = f        for even k      (out and back: a triangle between 0 and 1
//                = 1 - f    for odd k        that starts at 0)
//   out(t) = offset                                                for tau < 0
//          = offset + amplitude * sweep(tau) + advance * p(tau)   for tau >= 0
//   p(tau) = k + f   (advance_mode: ramp, default: the advancing axis moves while the other
//                     sweeps, so the path is a continuous zig-zag line)
//          = k       (advance_mode: step: the increment is added at each turning point)
// Either way the advancing axis has moved exactly k * advance at the k-th turning point.
// With `cycles` = N the path stops at tau = N * period_s and holds that value
// (offset + 2 N advance, the sweeping axis back at offset).
//
// Threads: configure()/activate() on the loader thread, step() on the RT thread;
// set_tunable() on the RT thread at a cycle boundary.
#pragma once

#include <cstdint>
#include <vector>

#include "element_source.hpp"
#include "source_elements.hpp"

namespace lode::plugins {

class ZigzagSource final : public source::ElementSource {
 public:
  Status configure(ConfigureContext& ctx) override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  // `lode set`: offset.<element> and amplitude.<element>, stored by
  // ElementSource::set_tunable(). step() is a function of time only: the path from the next
  // sample on is the one the new value describes (a new amplitude rescales the current sweep
  // position).

 private:
  std::vector<double> amplitude_;
  std::vector<double> advance_;
  std::int64_t period_ns_ = 0;
  std::int64_t start_ns_ = 0;
  bool has_cycles_ = false;
  std::int64_t end_ns_ = 0;  ///< elapsed time at which the path stops (cycles * period)
  bool advance_in_steps_ = false;
};

}  // namespace lode::plugins
