// What a hot swap costs the RT thread: config/kawato_planar_swap.yaml at 5 kHz,
// the benchmark thread playing the RT thread (before_cycle hooks, run_cycle, after_cycle).
//
//   ./build/tests/lode_hot_swap_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
//   plain_cycle          a whole cycle with nothing to swap (the hooks return at once)
//   exchange/warm        the RT part of one swap Kalman <-> hybrid H2/Hinf with state hand-over:
//                        the prefetch (one cycle ahead), export, mapped copy, import, port
//                        re-binding, Block* exchange, and the end-of-cycle input snapshot;
//                        manual time = the hook parts of both cycles only
//   exchange/cold        the same without the state hand-over
//   exchange/warm_prepared_on_other_core
//                        exchange/warm with the newcomer prepared by a thread on another CPU,
//                        as in `lode run`: the exchange's data arrive from that core's cache
//   swap_cycles          the two whole cycles of a warm swap, just after its preparation
//   cycles_after_prepare the same two cycles after the same preparation, without a swap: the
//                        swap's extra cost is swap_cycles - cycles_after_prepare
//
// Preparation (load, configure, activate: off the RT thread) runs untimed between iterations.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include <pthread.h>
#include <sched.h>

#include "lode/event_log.hpp"
#include "lode/hot_swap.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace {

const char* kHybridParams =
    "{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], hinf_theta: 1.0e8, d: 0.5, output: predicted}";
const char* kKalmanParams =
    "{motion: constant_acceleration, q: [1.0e2, 1.0e2, 1.0e5], p0: 1.0e-8, r: [2.2e-10, 2.2e-10, 9.6e-9], "
    "output: predicted}";

struct Rig {
  Rig() {
    std::ifstream in(std::string(LODE_SOURCE_DIR) + "/config/kawato_planar_swap.yaml");
    std::stringstream text;
    text << in.rdbuf();
    lode::Diagnostics diag;
    pipeline = lode::Pipeline::load_text(text.str(), "kawato_planar_swap.yaml", registry, diag);
    if (!pipeline || !pipeline->activate()) {
      std::fprintf(stderr, "hot_swap_bench: cannot load config/kawato_planar_swap.yaml:\n%s", diag.format().c_str());
      std::exit(1);
    }
    swapper = std::make_unique<lode::HotSwap>(*pipeline, events);
    swapper->set_running(true);
    for (int i = 0; i < 2000; ++i) cycle();  // past the start-up transient
  }
  lode::Tick next() {
    lode::Tick t;
    t.cycle = n++;
    t.time_ns = static_cast<std::int64_t>(t.cycle) * pipeline->period_ns();
    t.dt_s = 1.0 / pipeline->rate_hz();
    return t;
  }
  void cycle() {
    const auto t = next();
    swapper->before_cycle(t);
    benchmark::DoNotOptimize(pipeline->run_cycle(t, false));
    swapper->after_cycle(t);
  }
  lode::EventLog events;
  lode::PluginRegistry registry;
  std::unique_ptr<lode::Pipeline> pipeline;
  std::unique_ptr<lode::HotSwap> swapper;
  std::uint64_t n = 0;
  bool hybrid = false;  ///< which plugin is in the role now
};

/// One settled pipeline per benchmark: cold swaps every 4 ms upset the closed loop (the
/// newcomer starts from zero), which would slow every benchmark that ran after them.
enum class Bench { plain, warm, cold, other_core, swap_cycle, after_prepare };
Rig& rig(Bench which) {
  static std::map<Bench, std::unique_ptr<Rig>> rigs;
  auto& r = rigs[which];
  if (!r) r = std::make_unique<Rig>();
  return *r;
}

/// The next request of the back-and-forth: hybrid when Kalman runs, Kalman when hybrid does.
lode::SwapRequest next_request(Rig& r, bool warm) {
  lode::SwapRequest q;
  q.block = "kf";
  q.plugin = r.hybrid ? "estimator.kalman" : "estimator.hybrid_h2hinf";
  q.params = r.hybrid ? kKalmanParams : kHybridParams;
  q.warm_start = warm;
  return q;
}

/// Pins the calling thread to one CPU (false where the host refuses or has one CPU).
bool pin_to_cpu(int cpu) {
  if (std::thread::hardware_concurrency() < 2) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
}

/// Prepares on this thread, or (as `lode run` does: the command thread prepares, the RT
/// thread exchanges) on a thread pinned to CPU 0 while this one runs on CPU 1.
lode::Expected<lode::HotSwap::PreparedPtr> prepare_for(Rig& r, bool warm, bool other_core) {
  if (!other_core) return r.swapper->prepare(next_request(r, warm));
  lode::Expected<lode::HotSwap::PreparedPtr> prepared = lode::Status::error("not prepared");
  std::thread preparer([&] {
    pin_to_cpu(0);
    prepared = r.swapper->prepare(next_request(r, warm));
  });
  preparer.join();
  return prepared;
}

/// Times the RT hook parts of one swap (the prefetch at the start of a cycle, the exchange at
/// its end, the input snapshot at the end of the next); the cycles themselves run untimed.
void exchange(benchmark::State& state, bool warm, bool other_core = false) {
  Rig& r = rig(other_core ? Bench::other_core : warm ? Bench::warm : Bench::cold);
  if (other_core && !pin_to_cpu(1)) {
    state.SkipWithError("cannot pin threads to CPUs 0 and 1");
    return;
  }
  for (auto _ : state) {
    auto prepared = prepare_for(r, warm, other_core);
    if (!prepared) {
      state.SkipWithError(prepared.error().c_str());
      return;
    }
    r.swapper->post(**prepared);
    std::chrono::steady_clock::duration hooks{};
    while (!r.swapper->done()) {
      const auto t = r.next();
      const auto t0 = std::chrono::steady_clock::now();
      r.swapper->before_cycle(t);
      const auto t1 = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(r.pipeline->run_cycle(t, false));
      const auto t2 = std::chrono::steady_clock::now();
      r.swapper->after_cycle(t);
      const auto t3 = std::chrono::steady_clock::now();
      hooks += (t1 - t0) + (t3 - t2);
    }
    state.SetIterationTime(std::chrono::duration<double>(hooks).count());
    const auto report = r.swapper->finish(std::move(*prepared));
    if (!report.ok) {
      state.SkipWithError(report.message.c_str());
      return;
    }
    r.hybrid = !r.hybrid;
    for (int i = 0; i < 20; ++i) r.cycle();  // let the newcomer settle before the next swap
  }
  state.counters["hot_swap_rt_cost_p50_ns"] = static_cast<double>(r.swapper->rt_cost().percentile(0.5));
}

void BM_PlainCycle(benchmark::State& state) {
  Rig& r = rig(Bench::plain);
  for (auto _ : state) r.cycle();
}
BENCHMARK(BM_PlainCycle)->Name("plain_cycle");

void BM_ExchangeWarm(benchmark::State& state) { exchange(state, true); }
BENCHMARK(BM_ExchangeWarm)->Name("exchange/warm")->UseManualTime()->Iterations(2000);

void BM_ExchangeCold(benchmark::State& state) { exchange(state, false); }
BENCHMARK(BM_ExchangeCold)->Name("exchange/cold")->UseManualTime()->Iterations(2000);

void BM_ExchangeWarmOtherCore(benchmark::State& state) { exchange(state, true, true); }
BENCHMARK(BM_ExchangeWarmOtherCore)->Name("exchange/warm_prepared_on_other_core")->UseManualTime()->Iterations(2000);

/// Two whole cycles right after a preparation on this thread: with a swap posted (the
/// prefetch cycle and the exchange cycle), or without (the control). The counter
/// second_cycle_ns is the mean of the second cycle alone (the exchange cycle, with a swap).
void two_cycles_after_prepare(benchmark::State& state, bool post) {
  Rig& r = rig(post ? Bench::swap_cycle : Bench::after_prepare);
  double second_total = 0.0;
  for (auto _ : state) {
    auto prepared = r.swapper->prepare(next_request(r, true));
    if (!prepared) {
      state.SkipWithError(prepared.error().c_str());
      return;
    }
    if (post) r.swapper->post(**prepared);
    const auto t0 = std::chrono::steady_clock::now();
    r.cycle();
    const auto t1 = std::chrono::steady_clock::now();
    r.cycle();
    const auto t2 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t2 - t0).count());
    second_total += std::chrono::duration<double, std::nano>(t2 - t1).count();
    if (post) {
      if (!r.swapper->done() || !r.swapper->finish(std::move(*prepared)).ok) {
        state.SkipWithError("swap not done in two cycles, or refused");
        return;
      }
      r.hybrid = !r.hybrid;
    } else {
      prepared->reset();  // never posted: the newcomer is simply destroyed
    }
    for (int i = 0; i < 20; ++i) r.cycle();
  }
  state.counters["second_cycle_ns"] = second_total / static_cast<double>(state.iterations());
}

void BM_SwapCycles(benchmark::State& state) { two_cycles_after_prepare(state, true); }
BENCHMARK(BM_SwapCycles)->Name("swap_cycles")->UseManualTime()->Iterations(2000);

/// The control for swap_cycles: preparing (dlopen, configure, activate: ~0.7 ms) evicts part
/// of the pipeline's data from this core's caches, so the cycles after it are slower with or
/// without a swap; the swap's own extra cost is swap_cycles - cycles_after_prepare.
void BM_CyclesAfterPrepare(benchmark::State& state) { two_cycles_after_prepare(state, false); }
BENCHMARK(BM_CyclesAfterPrepare)->Name("cycles_after_prepare")->UseManualTime()->Iterations(2000);

}  // namespace

BENCHMARK_MAIN();
