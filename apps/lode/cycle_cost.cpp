#include "cycle_cost.hpp"

#include "lode/scheduler.hpp"

namespace lode::cli {

std::string run_cycles_timed(Pipeline& p, std::uint64_t cycles, Histogram& whole) {
  if (auto st = p.activate(); !st) return st.message();
  Tick tick;
  tick.dt_s = 1.0 / p.rate_hz();
  RealClock clock;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p.period_ns();
    const auto t0 = clock.now_ns();
    const auto r = p.run_cycle(tick, true);
    whole.record(clock.now_ns() - t0);
    if (r.status != StepStatus::ok)
      return "fault at cycle " + std::to_string(k) + " in " + p.ops()[static_cast<std::size_t>(r.failed_op)].label;
  }
  p.deactivate();
  return "";
}

}  // namespace lode::cli
