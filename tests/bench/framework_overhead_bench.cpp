// What the framework costs around kawato_planar's math: the same blocks' step() and write()
// called back to back on their bound storage ("direct": no Pipeline::run_cycle, no op timing,
// no envelope, no scheduler, no hooks), against the same cycle run by the Scheduler on the
// simulated clock as `lode run` runs it (the ops of one cycle in eight timed), without and
// with the output digest `lode run` adds as a hook.
//
//   ./build/tests/lode_framework_overhead_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// Both start from freshly activated pipelines and must produce the same outputs, cycle for
// cycle: before timing, 2400 cycles of each are digested (XXH3 over every output of every
// cycle) and a difference fails the benchmark. The "overhead" benchmark alternates batches of
// the two, so that a noisy, shared machine slows both alike, and reports the ratio of the
// medians (overhead_percent = 100 * (scheduler / direct - 1)).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "output_digest.hpp"

namespace {

constexpr const char* kConfig = LODE_SOURCE_DIR "/config/kawato_planar.yaml";
constexpr std::uint64_t kBatch = 800;  // one simulated second

struct Loaded {
  lode::PluginRegistry registry;
  std::unique_ptr<lode::Pipeline> pipeline;
  std::string error;
  Loaded() {
    lode::Diagnostics diag;
    pipeline = lode::Pipeline::load_file(kConfig, registry, diag);
    if (!pipeline) error = diag.format();
    else if (auto st = pipeline->activate(); !st) error = st.message();
  }
};

/// kawato_planar's cycle without the framework: each op's block called in the pipeline's order.
class Direct {
 public:
  explicit Direct(lode::Pipeline& p) : p_(p) { tick_.dt_s = 1.0 / p.rate_hz(); }
  /// `cycles` cycles; false on a fault.
  bool run(std::uint64_t cycles, lode::cli::OutputDigest* digest = nullptr) {
    for (std::uint64_t k = 0; k < cycles; ++k) {
      tick_.cycle = next_++;
      tick_.time_ns = static_cast<std::int64_t>(tick_.cycle) * p_.period_ns();
      for (auto& op : p_.ops())
        if ((op.write_phase ? op.board->write(tick_) : op.block->step(tick_)) != lode::StepStatus::ok) return false;
      if (digest) digest->after_cycle(tick_);
    }
    return true;
  }

 private:
  lode::Pipeline& p_;
  lode::Tick tick_;
  std::uint64_t next_ = 0;
};

/// The same cycle through the Scheduler (simulated clock, op timing on as in `lode run`), with
/// or without the output digest `lode run` adds as a hook.
class Scheduled {
 public:
  Scheduled(lode::Pipeline& p, bool with_digest)
      : digest_(p.signals(), lode::cli::DigestAlgorithm::xxh3_64), scheduler_(p, clock_, events_) {
    if (with_digest) scheduler_.add_hook(&digest_);
    scheduler_.set_simulated_timing_stride(8);  // as RunServices sets it for `lode run`
  }
  bool run(std::uint64_t cycles) { return !scheduler_.run(cycles, stop_, nullptr).faulted; }
  lode::cli::OutputDigest& digest() { return digest_; }

 private:
  lode::SimulatedClock clock_;
  lode::EventLog events_;
  lode::cli::OutputDigest digest_;
  lode::Scheduler scheduler_;
  std::atomic<bool> stop_{false};
};

/// Fails the benchmark unless 2400 cycles give the same digest both ways.
bool same_outputs(benchmark::State& state) {
  Loaded a, b;
  if (!a.error.empty() || !b.error.empty()) {
    state.SkipWithError(("kawato_planar: " + a.error + b.error).c_str());
    return false;
  }
  lode::cli::OutputDigest direct_digest(a.pipeline->signals(), lode::cli::DigestAlgorithm::xxh3_64);
  Direct direct(*a.pipeline);
  Scheduled scheduled(*b.pipeline, true);
  if (!direct.run(2400, &direct_digest) || !scheduled.run(2400)) {
    state.SkipWithError("kawato_planar faulted");
    return false;
  }
  if (direct_digest.text() != scheduled.digest().text()) {
    state.SkipWithError(("outputs differ: direct " + direct_digest.text() + ", scheduler " +
                         scheduled.digest().text()).c_str());
    return false;
  }
  return true;
}

void BM_direct(benchmark::State& state) {
  if (!same_outputs(state)) return;
  Loaded l;
  Direct direct(*l.pipeline);
  for (auto _ : state)
    if (!direct.run(kBatch)) state.SkipWithError("fault");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kBatch));
}

void BM_scheduler(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  Loaded l;
  Scheduled scheduled(*l.pipeline, with_digest);
  for (auto _ : state)
    if (!scheduled.run(kBatch)) state.SkipWithError("fault");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kBatch));
}

double seconds(const std::chrono::steady_clock::time_point& since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

void BM_overhead(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  Loaded a, b;
  Direct direct(*a.pipeline);
  Scheduled scheduled(*b.pipeline, with_digest);
  std::vector<double> direct_ns, scheduled_ns;
  for (auto _ : state) {
    auto t = std::chrono::steady_clock::now();
    direct.run(kBatch);
    direct_ns.push_back(seconds(t) * 1e9 / kBatch);
    t = std::chrono::steady_clock::now();
    scheduled.run(kBatch);
    scheduled_ns.push_back(seconds(t) * 1e9 / kBatch);
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double d = median(direct_ns), s = median(scheduled_ns);
  state.counters["direct_ns_per_cycle"] = d;
  state.counters["scheduler_ns_per_cycle"] = s;
  state.counters["overhead_percent"] = 100.0 * (s / d - 1.0);
}

BENCHMARK(BM_direct)->Name("kawato_planar/direct")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_scheduler, scheduler, false)->Name("kawato_planar/scheduler")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_scheduler, scheduler_digest, true)
    ->Name("kawato_planar/scheduler+digest")
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_overhead, overhead, false)
    ->Name("kawato_planar/overhead")
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0);
BENCHMARK_CAPTURE(BM_overhead, overhead_digest, true)
    ->Name("kawato_planar/overhead+digest")
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
