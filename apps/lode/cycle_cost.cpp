#include "cycle_cost.hpp"

#include "lode/scheduler.hpp"
#include "output_digest.hpp"

namespace lode::cli {

std::string run_cycles_timed(Pipeline& p, std::uint64_t cycles, Histogram& whole, Histogram* digest_time) {
  if (auto st = p.activate(); !st) return st.message();
  OutputDigest digest(p.signals(), DigestAlgorithm::xxh3_64);
  Tick tick;
  tick.dt_s = 1.0 / p.rate_hz();
  RealClock clock;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p.period_ns();
    const auto t0 = clock.now_ns();
    const auto r = p.run_cycle(tick, true);
    const auto t1 = clock.now_ns();
    digest.after_cycle(tick);
    const auto t2 = clock.now_ns();
    whole.record(t2 - t0);
    if (digest_time) digest_time->record(t2 - t1);
    if (r.status != StepStatus::ok)
      return "fault at cycle " + std::to_string(k) + " in " + p.ops()[static_cast<std::size_t>(r.failed_op)].label;
  }
  p.deactivate();
  return "";
}

}  // namespace lode::cli
