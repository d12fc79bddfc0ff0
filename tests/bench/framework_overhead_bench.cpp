// What the framework costs around kawato_planar's math. Three ways to run one cycle:
//   by_hand    one hand-written function calling the plugins' kernels on plain arrays
//              (kawato_planar_by_hand.hpp: no pipeline, ports, plugin virtual calls or hooks);
//   direct     the pipeline's blocks' step() and write() back to back on their bound storage
//              (no Pipeline::run_cycle, no op timing, no envelope, no scheduler, no hooks);
//   scheduler  the Scheduler on the simulated clock as `lode run --clock sim` runs it (the ops
//              of every kSimulatedTimingStride-th cycle timed, the envelope checked), without
//              and with the output digest `lode run` adds as a hook.
//
//   ./build/tests/lode_framework_overhead_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// All start from freshly activated pipelines and must produce the same outputs, cycle for
// cycle: before timing, 2400 cycles of direct and scheduler are digested (XXH3 over every
// output of every cycle), and the hand-written function is compared with the scheduler value
// by value (every output of the pipeline, bit for bit) on every one of 2400 cycles; a
// difference fails the benchmark.
//
// The "overhead" benchmarks alternate short batches (kPairBatch cycles) of the baseline and the
// scheduler thousands of times, each timed in the thread's own CPU time (a preempted batch is
// not charged for the other engineer's build), which of the two goes first swapped every pair,
// and report the median of the per-pair ratios: a disturbance hits one pair, not the figure
// (overhead_percent = 100 * (median(scheduler / baseline) - 1); the quartiles beside it).
//
// "kawato_planar/digest_in_cycle" pairs the scheduler with and without the digest the same way:
// what the digest costs inside a real cycle, where its code and state are no longer hot in the
// caches and branch predictors as they are in lode_digest_bench's loop.
//
// "kawato_planar/instructions" runs kInstructionCycles cycles of each way inside its own
// function for callgrind to count (tests/bench/framework_overhead_instructions.sh): the
// deterministic figure, the same on any host.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <ctime>
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
// `lode run --clock sim` times the ops of one cycle in this many (kSimulatedTimingStride in
// apps/lode/run_services.hpp, whose header needs the DDS bridge's: keep the two equal).
constexpr std::uint64_t kTimingStride = 64;
// A multiple of every timing stride, so each batch times the same share of its cycles.
constexpr std::uint64_t kPairBatch = 64;
static_assert(kPairBatch % kTimingStride == 0);
constexpr std::int64_t kPairs = 4000;
constexpr std::uint64_t kInstructionCycles = 800;

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
  /// `timing_stride`: every how many cycles each op is timed; `lode run` times every 64th on
  /// the simulated clock, every cycle on the real clock (1).
  Scheduled(lode::Pipeline& p, bool with_digest, std::uint64_t timing_stride = kTimingStride)
      : digest_(p.signals(), lode::cli::DigestAlgorithm::xxh3_64), scheduler_(p, clock_, events_) {
    if (with_digest) scheduler_.add_hook(&digest_);
    scheduler_.set_simulated_timing_stride(timing_stride);
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
  scheduler.set_simulated_timing_stride(kTimingStride);
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

/// The scheduler timing every op of every cycle, as it does on the real clock (where each op's
/// execution time feeds the run summary and any step budget): what the clock reads cost.
void BM_scheduler_every_op_timed(benchmark::State& state) {
  if (!same_outputs(state)) return;
  Loaded l;
  Scheduled scheduled(*l.pipeline, false, 1);
  for (auto _ : state)
    if (!scheduled.run(kBatch)) state.SkipWithError("fault");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kBatch));
}

/// This thread's CPU time: a batch preempted by another process is not charged for it.
std::int64_t thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

template <typename Way>
double batch_cpu_ns(Way& way, benchmark::State& state) {
  const std::int64_t start = thread_cpu_ns();
  if (!way.run(kPairBatch)) state.SkipWithError("fault");
  return static_cast<double>(thread_cpu_ns() - start);
}

double quantile(std::vector<double> v, double q) {
  const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

/// kPairs pairs of kPairBatch-cycle batches, `baseline` and `measured`, the first of each pair
/// alternating; the medians of the per-pair ratios and differences.
template <typename Baseline, typename Measured>
void overhead(benchmark::State& state, Baseline& baseline, Measured& measured, const char* baseline_name,
              const char* measured_name) {
  std::vector<double> baseline_ns, measured_ns, ratios, differences;
  for (int warm = 0; warm < 8; ++warm) {
    batch_cpu_ns(baseline, state);
    batch_cpu_ns(measured, state);
  }
  bool baseline_first = true;
  for (auto _ : state) {
    double base = 0.0, meas = 0.0;
    if (baseline_first) {
      base = batch_cpu_ns(baseline, state);
      meas = batch_cpu_ns(measured, state);
    } else {
      meas = batch_cpu_ns(measured, state);
      base = batch_cpu_ns(baseline, state);
    }
    baseline_first = !baseline_first;
    baseline_ns.push_back(base / kPairBatch);
    measured_ns.push_back(meas / kPairBatch);
    ratios.push_back(meas / base);
    differences.push_back((meas - base) / kPairBatch);
  }
  state.counters[std::string(baseline_name) + "_ns_per_cycle"] = quantile(baseline_ns, 0.5);
  state.counters[std::string(measured_name) + "_ns_per_cycle"] = quantile(measured_ns, 0.5);
  state.counters["overhead_percent"] = 100.0 * (quantile(ratios, 0.5) - 1.0);
  state.counters["overhead_q1_percent"] = 100.0 * (quantile(ratios, 0.25) - 1.0);
  state.counters["overhead_q3_percent"] = 100.0 * (quantile(ratios, 0.75) - 1.0);
  state.counters["added_ns_per_cycle"] = quantile(differences, 0.5);
}

void BM_overhead(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  Loaded a, b;
  Direct direct(*a.pipeline);
  Scheduled scheduled(*b.pipeline, with_digest);
  overhead(state, direct, scheduled, "direct", "scheduler");
}

void BM_overhead_by_hand(benchmark::State& state, bool with_digest) {
  if (!same_outputs(state)) return;
  ByHand by_hand;
  Loaded b;
  Scheduled scheduled(*b.pipeline, with_digest);
  overhead(state, by_hand, scheduled, "by_hand", "scheduler");
}

/// What the output digest adds to a cycle where `lode run` computes it: the scheduler with
/// and without it, paired as above (added_ns_per_cycle: the median per-pair difference).
void BM_digest_in_cycle(benchmark::State& state) {
  if (!same_outputs(state)) return;
  Loaded a, b;
  Scheduled plain(*a.pipeline, false), digested(*b.pipeline, true);
  overhead(state, plain, digested, "scheduler", "scheduler_digest");
}

/// What timing every op of every cycle (the real clock's way) adds to a cycle: the scheduler
/// timing every 64th cycle and timing every cycle, paired as above.
void BM_op_timing_in_cycle(benchmark::State& state) {
  if (!same_outputs(state)) return;
  Loaded a, b;
  Scheduled sampled(*a.pipeline, false), every(*b.pipeline, false, 1);
  overhead(state, sampled, every, "sampled", "every_op_timed");
}

// One function per way, each running kInstructionCycles cycles, for callgrind's
// --toggle-collect (framework_overhead_instructions.sh): its inclusive instruction count is
// that way's, nothing of the set-up or the checks around it.
[[gnu::noinline, gnu::noipa]] bool instructions_by_hand(ByHand& w) { return w.run(kInstructionCycles); }
[[gnu::noinline, gnu::noipa]] bool instructions_direct(Direct& w) { return w.run(kInstructionCycles); }
[[gnu::noinline, gnu::noipa]] bool instructions_scheduler(Scheduled& w) { return w.run(kInstructionCycles); }
[[gnu::noinline, gnu::noipa]] bool instructions_scheduler_digest(Scheduled& w) { return w.run(kInstructionCycles); }

void BM_instructions(benchmark::State& state) {
  if (!same_outputs(state)) return;
  ByHand by_hand;
  Loaded a, b, c;
  Direct direct(*a.pipeline);
  Scheduled scheduled(*b.pipeline, false), scheduled_digest(*c.pipeline, true);
  for (auto _ : state) {
    // Each way's first second outside the count: what is counted is the steady cycle.
    const bool warm = by_hand.run(kBatch) && direct.run(kBatch) && scheduled.run(kBatch) && scheduled_digest.run(kBatch);
    if (!warm || !instructions_by_hand(by_hand) || !instructions_direct(direct) ||
        !instructions_scheduler(scheduled) || !instructions_scheduler_digest(scheduled_digest))
      state.SkipWithError("fault");
  }
  state.counters["cycles_per_way"] = static_cast<double>(kInstructionCycles);
}

BENCHMARK(BM_by_hand)->Name("kawato_planar/by_hand")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_direct)->Name("kawato_planar/direct")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_scheduler, scheduler, false)->Name("kawato_planar/scheduler")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_scheduler_every_op_timed)->Name("kawato_planar/scheduler_every_op_timed")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_op_timing_in_cycle)
    ->Name("kawato_planar/op_timing_in_cycle")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK_CAPTURE(BM_scheduler, scheduler_digest, true)
    ->Name("kawato_planar/scheduler+digest")
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_overhead, overhead, false)
    ->Name("kawato_planar/overhead")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK_CAPTURE(BM_overhead, overhead_digest, true)
    ->Name("kawato_planar/overhead+digest")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK_CAPTURE(BM_overhead_by_hand, overhead_by_hand, false)
    ->Name("kawato_planar/overhead_vs_by_hand")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK_CAPTURE(BM_overhead_by_hand, overhead_by_hand_digest, true)
    ->Name("kawato_planar/overhead_vs_by_hand+digest")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK(BM_digest_in_cycle)
    ->Name("kawato_planar/digest_in_cycle")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(kPairs);
BENCHMARK(BM_instructions)->Name("kawato_planar/instructions")->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
