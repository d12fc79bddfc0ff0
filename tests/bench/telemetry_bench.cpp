// What telemetry costs the RT thread: TelemetryTap::after_cycle() with N published
// signals (3 values each), measured per call the way the RT thread calls it: once per
// cycle (here every 50 us, a 20 kHz loop), with the consumer draining every millisecond as
// the DDS bridge's publisher thread does. Reported per cycle and per published signal.
// Then what the RT thread's doorbell costs it: PublishDoorbell::ring() with the publisher
// awake (an atomic add and a load) and with the publisher asleep on it (plus a FUTEX_WAKE).
// The end-to-end latency (RT capture -> subscriber in another process) is measured by
// tests/bench/telemetry_latency.sh with `lode echo --latency`.
#include <benchmark/benchmark.h>
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "lode/telemetry.hpp"

namespace {

using Clock = std::chrono::steady_clock;

void spin_for(std::chrono::nanoseconds d) {
  const auto until = Clock::now() + d;
  while (Clock::now() < until) {
  }
}

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
  lode::TelemetryTap tap(spec, 20000.0);
  std::atomic<bool> stop{false};
  std::thread consumer;
  if (drained)
    consumer = std::thread([&] {
      lode::SampleHeader h;
      while (!stop.load(std::memory_order_relaxed)) {
        for (auto& c : tap.channels())
          while (c.ring->front(h)) c.ring->pop();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
  lode::Tick tick;
  for (auto _ : state) {
    spin_for(std::chrono::microseconds(50));  // the rest of the cycle (not timed)
    const auto t0 = Clock::now();
    tap.after_cycle(tick);
    const auto t1 = Clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    ++tick.cycle;
  }
  stop = true;
  if (consumer.joinable()) consumer.join();
  state.counters["signals"] = static_cast<double>(signals);
  state.counters["dropped"] = static_cast<double>(tap.dropped());
}
// Second argument: 1 = drained every ms (normal), 0 = nobody drains (a stuck publisher:
// after the ring fills, every push is a counted drop).
BENCHMARK(BM_TelemetryCapture)->ArgsProduct({{1, 4, 16}, {1, 0}})->UseManualTime()->Iterations(40000);

void BM_DoorbellRing(benchmark::State& state) {
  // 0: the publisher is busy or aimed past the capture, as the bridge arranges (it looks at
  //    the sequence, never sleeps on the doorbell);
  // 1: the publisher sleeps on the doorbell, so every ring() has to wake it.
  const bool asleep = state.range(0) != 0;
  lode::PublishDoorbell doorbell;
  std::atomic<bool> stop{false};
  std::thread publisher([&] {
    std::uint32_t seen = doorbell.sequence();
    while (!stop.load(std::memory_order_relaxed)) {
      if (asleep) {
        doorbell.wait(seen, std::chrono::milliseconds(100));
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      seen = doorbell.sequence();
    }
  });
  // Ring from a SCHED_FIFO thread where allowed, as the RT thread does: the woken publisher
  // (normal priority) then cannot preempt it inside the measurement.
  sched_param fifo{};
  fifo.sched_priority = 80;
  const bool realtime = pthread_setschedparam(pthread_self(), SCHED_FIFO, &fifo) == 0;
  for (auto _ : state) {
    spin_for(std::chrono::microseconds(50));  // the rest of the cycle: the publisher goes back to sleep
    const auto t0 = Clock::now();
    doorbell.ring();
    const auto t1 = Clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
  }
  sched_param normal{};
  if (realtime) pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  state.counters["sched_fifo"] = realtime ? 1 : 0;
  stop = true;
  doorbell.wake_all();
  publisher.join();
  state.counters["wakes_per_ring"] =
      static_cast<double>(doorbell.wakes()) / static_cast<double>(std::max<std::int64_t>(state.iterations(), 1));
}
BENCHMARK(BM_DoorbellRing)->Arg(0)->Arg(1)->UseManualTime()->Iterations(40000);

void BM_ClockPairOverhead(benchmark::State& state) {
  // The two Clock::now() calls around each measurement, to subtract by eye.
  for (auto _ : state) {
    const auto t0 = Clock::now();
    const auto t1 = Clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
  }
}
BENCHMARK(BM_ClockPairOverhead)->UseManualTime()->Iterations(40000);

}  // namespace

BENCHMARK_MAIN();
