// lode bench CONFIG: per-block, output-digest and whole-cycle cost, the cycle run back to back
// on the calling thread (no scheduler, no sleeping), timed with the monotonic clock.
#include <cstdio>

#include "commands.hpp"
#include "cycle_cost.hpp"
#include "load_config.hpp"
#include "lode/scheduler.hpp"

namespace lode::cli {
namespace {

constexpr long long kDefaultCycles = 100000;

std::size_t output_bytes(const Pipeline& p) {
  std::size_t n = 0;
  for (const auto& s : p.signals()) n += s.size() * sizeof(double);
  return n;
}

int bench(const Args& args) {
  auto loaded = load_config(args.positional.at(0));
  if (!loaded) return kExitConfig;
  auto& p = loaded->pipeline;
  const auto cycles = static_cast<std::uint64_t>(args.integer("--cycles", kDefaultCycles));
  Histogram whole, digest;
  if (const auto error = run_cycles_timed(*p, cycles, whole, &digest); !error.empty()) {
    std::fprintf(stderr, "lode: %s\n", error.c_str());
    return kExitFault;
  }
  std::printf("%-22s %10s %10s %10s %10s\n", "operation", "p50 ns", "p99 ns", "mean ns", "max ns");
  for (const auto& op : p->ops())
    std::printf("%-22s %10lld %10lld %10.0f %10lld\n", op.label.c_str(),
                static_cast<long long>(op.exec_time->percentile(0.5)),
                static_cast<long long>(op.exec_time->percentile(0.99)), op.exec_time->mean(),
                static_cast<long long>(op.exec_time->max()));
  // lode run hashes every output after every cycle on the RT thread: part of the cycle's cost.
  std::printf("%-22s %10lld %10lld %10.0f %10lld   (xxh3-64 over %zu bytes)\n", "output digest",
              static_cast<long long>(digest.percentile(0.5)), static_cast<long long>(digest.percentile(0.99)),
              digest.mean(), static_cast<long long>(digest.max()), output_bytes(*p));
  // The digest's line is one pair of clock reads around a call of tens of ns: that pair's own
  // cost, measured the same way, is what to subtract from it.
  Histogram timer;
  RealClock clock;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    const auto t0 = clock.now_ns();
    const auto t1 = clock.now_ns();
    timer.record(t1 - t0);
  }
  std::printf("%-22s %10lld %10lld %10.0f %10lld   (two clock reads and nothing between: in every line above)\n",
              "timer", static_cast<long long>(timer.percentile(0.5)), static_cast<long long>(timer.percentile(0.99)),
              timer.mean(), static_cast<long long>(timer.max()));
  std::printf("%-22s %10lld %10lld %10.0f %10lld   (%llu cycles, digest and timing overhead included)\n",
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
