// Per-block step cost and whole-cycle cost of the shipped pipelines (Google Benchmark).
//   ./build/tests/lode_pipeline_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace {

struct Loaded {
  lode::PluginRegistry registry;
  std::unique_ptr<lode::Pipeline> pipeline;
  lode::Tick tick;
  std::uint64_t cycle = 0;
};

Loaded& kawato() {
  static std::unique_ptr<Loaded> l = [] {
    auto x = std::make_unique<Loaded>();
    lode::Diagnostics diag;
    x->pipeline = lode::Pipeline::load_file(LODE_SOURCE_DIR "/config/kawato_planar.yaml", x->registry, diag);
    if (!x->pipeline || !x->pipeline->activate()) {
      std::fputs(diag.format().c_str(), stderr);
      std::abort();
    }
    x->tick.dt_s = 1.0 / x->pipeline->rate_hz();
    return x;
  }();
  return *l;
}

void advance(Loaded& l) {
  l.tick.cycle = l.cycle++;
  l.tick.time_ns = static_cast<std::int64_t>(l.tick.cycle) * l.pipeline->period_ns();
}

void BM_KawatoWholeCycle(benchmark::State& state) {
  auto& l = kawato();
  for (auto _ : state) {
    advance(l);
    benchmark::DoNotOptimize(l.pipeline->run_cycle(l.tick, false));
  }
}
BENCHMARK(BM_KawatoWholeCycle);

// One operation of the cycle in isolation (the others run untimed so inputs stay live).
void BM_KawatoOp(benchmark::State& state) {
  auto& l = kawato();
  auto& ops = l.pipeline->ops();
  const auto index = static_cast<std::size_t>(state.range(0));
  state.SetLabel(ops[index].label);
  // Manual time around the one op: PauseTiming() costs more than the cheaper blocks.
  for (auto _ : state) {
    advance(l);
    for (std::size_t i = 0; i < index; ++i)
      ops[i].write_phase ? ops[i].block->write(l.tick) : ops[i].block->step(l.tick);
    auto& op = ops[index];
    const auto t0 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(op.write_phase ? op.block->write(l.tick) : op.block->step(l.tick));
    const auto t1 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    for (std::size_t i = index + 1; i < ops.size(); ++i)
      ops[i].write_phase ? ops[i].block->write(l.tick) : ops[i].block->step(l.tick);
  }
}
BENCHMARK(BM_KawatoOp)->DenseRange(0, 5)->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
