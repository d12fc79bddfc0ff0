// What the framework costs around kawato_planar's math. Three ways to run one cycle:
//   by_hand    one hand-written function calling the plugins' kernels on plain arrays
//              (kawato_planar_by_hand.hpp: no pipeline, ports, plugin virtual calls or hooks);
//   direct     the pipeline's blocks' step() and write() back to back on their bound storage
//              (no Pipeline::run_cycle, no op timing, no envelope, no scheduler, no hooks);
//   scheduler  the Scheduler on the simulated clock as `lode run --clock sim` runs it (the ops
//              of one cycle in eight timed, the envelope checked), without and with the output
//              digest `lode run` adds as a hook.
//
//   ./build/tests/lode_framework_overhead_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// All start from freshly activated pipelines and must produce the same outputs, cycle for
// cycle: before timing, 2400 cycles of direct and scheduler are digested (XXH3 over every
// output of every cycle), and the hand-written function is compared with the scheduler value
// by value (every output of the pipeline, bit for bit) on every one of 2400 cycles; a
// difference fails the benchmark. The "overhead" benchmarks alternate batches of the baseline
// and the scheduler, so that a noisy, shared machine slows both alike, and report the ratio of
// the medians (overhead_percent = 100 * (scheduler / baseline - 1)).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "kawato_planar_by_hand.hpp"
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

/// The hand-written function, with the pipeline that lends it the GLSDC.
class ByHand {
 public:
  ByHand() : by_hand_(*lender_.pipeline) {}
  [[nodiscard]] std::string error() const { return lender_.error.empty() ? by_hand_.error() : lender_.error; }
  /// Cycles 0 ... cycles - 1, numbered as Scheduler::run numbers each call's (the state goes on).
  bool run(std::uint64_t cycles) {
    for (std::uint64_t k = 0; k < cycles; ++k)
      if (!by_hand_.cycle(k)) return false;
    return true;
  }
  lode::bench::KawatoPlanarByHand& function() { return by_hand_; }

 private:
  Loaded lender_;
  lode::bench::KawatoPlanarByHand by_hand_;
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

/// After each of the scheduler's cycles, the hand-written function's cycle of the same number,
/// then every output of the pipeline against it, bit for bit; keeps the first difference.
class CompareByHand final : public lode::CycleHook {
 public:
  CompareByHand(lode::bench::KawatoPlanarByHand& by_hand, const lode::Pipeline& pipeline)
      : by_hand_(by_hand), signals_(pipeline.signals()) {}
  void after_cycle(const lode::Tick& tick) noexcept override {
    if (!difference_.empty()) return;
    const std::string cycle = "cycle " + std::to_string(tick.cycle);
    if (!by_hand_.cycle(tick.cycle)) {
      difference_ = "the hand-written function faulted on " + cycle;
      return;
    }
    const auto& mine = by_hand_.outputs();
    for (const lode::SignalRef& signal : signals_) {
      const auto it = mine.find(signal.name());
      if (it == mine.end() || it->second.size != signal.size()) {
        difference_ = "the hand-written function does not compute " + signal.name();
        return;
      }
      for (std::size_t i = 0; i < signal.size(); ++i) {
        if (std::memcmp(&it->second.data[i], &signal.data[i], sizeof(double)) != 0) {
          char values[96];
          std::snprintf(values, sizeof values, "%.17g by hand, %.17g in the pipeline", it->second.data[i],
                        signal.data[i]);
          difference_ = "hand-written and pipeline differ on " + cycle + ", " + signal.name() + "[" +
                        std::to_string(i) + "]: " + values;
          return;
        }
      }
    }
  }
  [[nodiscard]] const std::string& difference() const { return difference_; }

 private:
  lode::bench::KawatoPlanarByHand& by_hand_;
  std::vector<lode::SignalRef> signals_;
  std::string difference_;
};

/// Why the hand-written function and the scheduler differ on some output of some cycle in the
/// first 2400 ("" when they agree bit for bit on every output the pipeline has).
std::string by_hand_differs() {
  ByHand by_hand;
  if (!by_hand.error().empty()) return "hand-written kawato_planar: " + by_hand.error();
  Loaded reference;
  if (!reference.error.empty()) return "kawato_planar: " + reference.error;
  lode::SimulatedClock clock;
  lode::EventLog events;
  lode::Scheduler scheduler(*reference.pipeline, clock, events);
  scheduler.set_simulated_timing_stride(8);
  CompareByHand compare(by_hand.function(), *reference.pipeline);
  scheduler.add_hook(&compare);
  std::atomic<bool> stop{false};
  if (scheduler.run(2400, stop, nullptr).faulted) return "the scheduler faulted";
  return compare.difference();
}

/// Fails the benchmark unless 2400 cycles give the same outputs every way.
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
  if (std::string why = by_hand_differs(); !why.empty()) {
    state.SkipWithError(why.c_str());
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

void BM_by_hand(benchmark::State& state) {
  if (!same_outputs(state)) return;
  ByHand by_hand;
  for (auto _ : state)
    if (!by_hand.run(kBatch)) state.SkipWithError("fault");
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

/// Alternating batches of `baseline` (by hand or direct) and the scheduler; medians per cycle.
template <typename Baseline>
void overhead(benchmark::State& state, Baseline& baseline, bool with_digest, const char* baseline_name) {
  Loaded b;
  Scheduled scheduled(*b.pipeline, with_digest);
  std::vector<double> baseline_ns, scheduled_ns;
  for (auto _ : state) {
    auto t = std::chrono::steady_clock::now();
    if (!baseline.run(kBatch)) state.SkipWithError("fault");
    baseline_ns.push_back(seconds(t) * 1e9 / kBatch);
    t = std::chrono::steady_clock::now();
    if (!scheduled.run(kBatch)) state.SkipWithError("fault");
    scheduled_ns.push_back(seconds(t) * 1e9 / kBatch);
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double d = median(baseline_ns), s = median(scheduled_ns);
  state.counters[std::string(baseline_name) + "_ns_per_cycle"] = d;
  state.counters["scheduler_ns_per_cycle"] = s;
  state.counters["overhead_percent"] = 100.0 * (s / d - 1.0);
}

void BM_overhead(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  Loaded a;
  Direct direct(*a.pipeline);
  overhead(state, direct, with_digest, "direct");
}

void BM_overhead_by_hand(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  ByHand by_hand;
  overhead(state, by_hand, with_digest, "by_hand");
}

BENCHMARK(BM_by_hand)->Name("kawato_planar/by_hand")->Unit(benchmark::kMicrosecond);
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

BENCHMARK_CAPTURE(BM_overhead_by_hand, overhead_by_hand, false)
    ->Name("kawato_planar/overhead_vs_by_hand")
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0);
BENCHMARK_CAPTURE(BM_overhead_by_hand, overhead_by_hand_digest, true)
    ->Name("kawato_planar/overhead_vs_by_hand+digest")
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
