// The output digest's cost per cycle on kawato_planar's outputs (384 bytes), with the XXH3-64
// that `lode run` computes and with the byte-wise FNV-1a that replays of older recordings use.
//
//   ./build/tests/lode_digest_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// The hash's cost does not depend on the values, so each iteration digests the same outputs
// (those of a few real cycles) and times nothing else.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "output_digest.hpp"

namespace {

void digest_kawato_planar(benchmark::State& state, lode::cli::DigestAlgorithm algorithm) {
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_file(LODE_SOURCE_DIR "/config/kawato_planar.yaml", registry, diag);
  if (!p || !p->activate()) {
    state.SkipWithError(("kawato_planar: " + diag.format()).c_str());
    return;
  }
  lode::Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  for (std::uint64_t k = 0; k < 100; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    (void)p->run_cycle(tick, false);
  }
  lode::cli::OutputDigest digest(p->signals(), algorithm);
  for (auto _ : state) {
    digest.after_cycle(tick);
    benchmark::ClobberMemory();
  }
  benchmark::DoNotOptimize(digest.value());
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(digest.cycle_bytes()));
  state.counters["bytes_per_cycle"] = static_cast<double>(digest.cycle_bytes());
  p->deactivate();
}

BENCHMARK_CAPTURE(digest_kawato_planar, xxh3_64, lode::cli::DigestAlgorithm::xxh3_64);
BENCHMARK_CAPTURE(digest_kawato_planar, fnv1a_64, lode::cli::DigestAlgorithm::fnv1a_64);

}  // namespace

BENCHMARK_MAIN();
