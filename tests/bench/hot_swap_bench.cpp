// What a hot swap costs the RT thread (issue 5): config/kawato_planar_swap.yaml at 5 kHz,
// the benchmark thread playing the RT thread (before_cycle hooks, run_cycle, after_cycle).
//
//   ./build/tests/lode_hot_swap_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
//   plain_cycle          a whole cycle with nothing to swap (the hooks return at once)
//   exchange/warm        the RT part of one swap Kalman <-> hybrid H2/Hinf with state hand-over:
//                        export, mapped copy, import, port re-binding, Block* exchange, and the
//                        end-of-cycle arena snapshot; manual time = both boundary parts only
//   exchange/cold        the same without the state hand-over
//   swap_cycle           the whole cycle in which a warm swap happens, just after its preparation
//   cycle_after_prepare  the same cycle after the same preparation, without a swap: the
//                        swap's extra cost at its cycle is swap_cycle - cycle_after_prepare
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
enum class Bench { plain, warm, cold, swap_cycle, after_prepare };
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

/// Times the two RT boundary parts of one exchange; the cycle between them runs untimed.
void exchange(benchmark::State& state, bool warm) {
  Rig& r = rig(warm ? Bench::warm : Bench::cold);
  for (auto _ : state) {
    auto prepared = r.swapper->prepare(next_request(r, warm));
    if (!prepared) {
      state.SkipWithError(prepared.error().c_str());
      return;
    }
    r.swapper->post(**prepared);
    const auto t = r.next();
    const auto t0 = std::chrono::steady_clock::now();
    r.swapper->before_cycle(t);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(r.pipeline->run_cycle(t, false));
    const auto t2 = std::chrono::steady_clock::now();
    r.swapper->after_cycle(t);
    const auto t3 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>((t1 - t0) + (t3 - t2)).count());
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

void BM_SwapCycle(benchmark::State& state) {
  Rig& r = rig(Bench::swap_cycle);
  for (auto _ : state) {
    auto prepared = r.swapper->prepare(next_request(r, true));
    if (!prepared) {
      state.SkipWithError(prepared.error().c_str());
      return;
    }
    r.swapper->post(**prepared);
    const auto t0 = std::chrono::steady_clock::now();
    r.cycle();
    const auto t1 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    if (!r.swapper->finish(std::move(*prepared)).ok) {
      state.SkipWithError("swap refused");
      return;
    }
    r.hybrid = !r.hybrid;
    for (int i = 0; i < 20; ++i) r.cycle();
  }
}
BENCHMARK(BM_SwapCycle)->Name("swap_cycle")->UseManualTime()->Iterations(2000);

/// The control for swap_cycle: the same preparation on the same thread just before, but no
/// swap posted. Preparing (dlopen, configure, activate: ~0.7 ms) evicts the pipeline's data
/// from this core's caches, so the first cycle after it is slow with or without a swap; the
/// swap's own extra cost is swap_cycle - cycle_after_prepare.
void BM_CycleAfterPrepare(benchmark::State& state) {
  Rig& r = rig(Bench::after_prepare);
  for (auto _ : state) {
    auto prepared = r.swapper->prepare(next_request(r, true));
    if (!prepared) {
      state.SkipWithError(prepared.error().c_str());
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    r.cycle();
    const auto t1 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    prepared->reset();  // never posted: the newcomer is simply destroyed
    for (int i = 0; i < 20; ++i) r.cycle();
  }
}
BENCHMARK(BM_CycleAfterPrepare)->Name("cycle_after_prepare")->UseManualTime()->Iterations(2000);

}  // namespace

BENCHMARK_MAIN();
