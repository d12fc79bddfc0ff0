// source.step: piecewise-constant reference (the thesis's step commands: 10 um, 100 um, 1 mm,
// 4 mm and 10 mm in Y; 100 urad, 1 mrad, 10 mrad in theta_z; Kawato 2005, Figs. 46-61).
//
// @system
// name: source.step
// output_ports:
//   out: [names...] with [units...]   # the value of the last step whose time has come
// @endsystem
//
// out(t) = offset                 for t <  steps[0].time_s
//        = steps[i].value         for steps[i].time_s <= t < steps[i+1].time_s
// with t the scheduled time of the cycle (tick.time_ns), so runs are deterministic.
//
// Threads: configure()/activate() on the loader thread, step() on the RT thread;
// set_tunable() on the RT thread at a cycle boundary.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "element_source.hpp"
#include "source_elements.hpp"

namespace lode::plugins {

class StepSource final : public source::ElementSource {
 public:
  Status configure(ConfigureContext& ctx) override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  // `lode set`: offset.<element> (the value before the first step), stored by
  // ElementSource::set_tunable(): step() reads the offset afresh each cycle, so the next
  // sample before the first step uses it.

 private:
  std::vector<std::int64_t> step_time_ns_;  ///< strictly increasing
  std::vector<double> step_values_;         ///< row-major: step x element
  std::size_t reached_hint_ = 0;            ///< steps reached at the last step() (a hint only)
};

}  // namespace lode::plugins
