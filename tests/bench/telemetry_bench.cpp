// What telemetry costs the RT thread: TelemetryTap::after_cycle() with N published
// signals (3 values each, every cycle), while a consumer thread drains the rings as the
// DDS bridge does. Reported per cycle and per published signal. The end-to-end latency
// (RT capture -> subscriber in another process) is measured by
// tests/bench/telemetry_latency.sh with `lode echo --latency`.
#include <benchmark/benchmark.h>

#include <atomic>
#include <thread>
#include <vector>

#include "lode/telemetry.hpp"

namespace {

void BM_TelemetryCapture(benchmark::State& state) {
  const auto signals = static_cast<std::size_t>(state.range(0));
  const bool drained = state.range(1) != 0;
  static const lode::Elements kElements = {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};
  std::vector<std::vector<double>> storage(signals, std::vector<double>(3, 1.0));
  lode::TelemetrySpec spec;
  for (std::size_t i = 0; i < signals; ++i) {
    lode::SignalRef ref{"b" + std::to_string(i), "out", storage[i].data(), &kElements};
    spec.signals.push_back({ref, 1, ""});
  }
  spec.ring_records = 1 << 14;
  lode::TelemetryTap tap(spec, 10000.0);
  std::atomic<bool> stop{false};
  std::thread consumer;
  if (drained)
    consumer = std::thread([&] {
      lode::SampleHeader h;
      while (!stop.load(std::memory_order_relaxed))
        for (auto& c : tap.channels())
          while (c.ring->front(h)) c.ring->pop();
    });
  lode::Tick tick;
  for (auto _ : state) {
    tap.after_cycle(tick);
    ++tick.cycle;
    benchmark::ClobberMemory();
  }
  stop = true;
  if (consumer.joinable()) consumer.join();
  state.counters["per_signal_ns"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * static_cast<double>(signals),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["dropped"] = static_cast<double>(tap.dropped());
}
// Second argument: 1 = a consumer drains (normal), 0 = nobody drains (every push drops:
// the cost of a stalled subscriber to the RT thread).
BENCHMARK(BM_TelemetryCapture)->ArgsProduct({{1, 4, 16}, {1, 0}})->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
