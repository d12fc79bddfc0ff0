// lode bench CONFIG: per-block and whole-cycle step cost, the cycle run back to back on the
// calling thread (no scheduler, no sleeping), timed with the monotonic clock.
#include <cstdio>

#include "commands.hpp"
#include "load_config.hpp"
#include "lode/scheduler.hpp"
#include "lode/sdk/histogram.hpp"

namespace lode::cli {
namespace {

constexpr long long kDefaultCycles = 100000;

int bench(const Args& args) {
  auto loaded = load_config(args.positional.at(0));
  if (!loaded) return kExitConfig;
  auto& p = loaded->pipeline;
  const auto cycles = static_cast<std::uint64_t>(args.integer("--cycles", kDefaultCycles));
  if (auto st = p->activate(); !st) {
    std::fprintf(stderr, "lode: %s\n", st.message().c_str());
    return kExitFault;
  }
  Histogram whole;
  Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  RealClock clock;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    const auto t0 = clock.now_ns();
    const auto r = p->run_cycle(tick, true);
    whole.record(clock.now_ns() - t0);
    if (r.status != StepStatus::ok) {
      std::fprintf(stderr, "lode: fault at cycle %llu in %s\n", static_cast<unsigned long long>(k),
                   p->ops()[static_cast<std::size_t>(r.failed_op)].label.c_str());
      return kExitFault;
    }
  }
  p->deactivate();
  std::printf("%-22s %10s %10s %10s %10s\n", "operation", "p50 ns", "p99 ns", "mean ns", "max ns");
  for (const auto& op : p->ops())
    std::printf("%-22s %10lld %10lld %10.0f %10lld\n", op.label.c_str(),
                static_cast<long long>(op.exec_time->percentile(0.5)),
                static_cast<long long>(op.exec_time->percentile(0.99)), op.exec_time->mean(),
                static_cast<long long>(op.exec_time->max()));
  std::printf("%-22s %10lld %10lld %10.0f %10lld   (%llu cycles, includes timing overhead)\n",
              "whole cycle", static_cast<long long>(whole.percentile(0.5)),
              static_cast<long long>(whole.percentile(0.99)), whole.mean(),
              static_cast<long long>(whole.max()), static_cast<unsigned long long>(cycles));
  return kExitOk;
}

}  // namespace

Command bench_command() {
  return {"bench", "per-block and whole-cycle step cost (simulated clock)",
          [](Declare& d) {
            d.positional("CONFIG", "the pipeline file", 1, 1);
            d.integer("--cycles", "N", "how many cycles (default " + std::to_string(kDefaultCycles) + ")", 1,
                      1000000000);
          },
          bench};
}

}  // namespace lode::cli
