// The cycle executive: one rate group, a real or simulated clock, timing statistics.
//
// Real clock: a dedicated thread with the pipeline's RT settings wakes on absolute
// deadlines (clock_nanosleep(TIMER_ABSTIME) on CLOCK_MONOTONIC), measures its wake-up
// latency, runs the cycle and accounts overruns; the calling thread stays non-RT and
// services `on_idle` (status line, draining taps and the RT log) ~20 times a second.
// Simulated clock: the same cycle runs back to back in the calling thread as fast as the
// CPU allows, with scheduled times advancing exactly one period per cycle.
#pragma once

#include <array>
#include <atomic>
#include <mutex>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/sdk/histogram.hpp"
#include "lode/pipeline.hpp"
#include "lode/telemetry.hpp"
#include "lode/sample_ring.hpp"

namespace lode {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual std::int64_t now_ns() noexcept = 0;
  virtual void sleep_until(std::int64_t deadline_ns) noexcept = 0;
  [[nodiscard]] virtual bool simulated() const noexcept = 0;
};

class RealClock final : public Clock {
 public:
  /// spin_ns > 0: sleep until that long before the deadline, then busy-wait to it.
  explicit RealClock(std::int64_t spin_ns = 0) : spin_ns_(spin_ns) {}
  std::int64_t now_ns() noexcept override;
  void sleep_until(std::int64_t deadline_ns) noexcept override;
  [[nodiscard]] bool simulated() const noexcept override { return false; }

 private:
  std::int64_t spin_ns_ = 0;
};

class SimulatedClock final : public Clock {
 public:
  std::int64_t now_ns() noexcept override { return now_; }
  void sleep_until(std::int64_t deadline_ns) noexcept override {
    if (deadline_ns > now_) now_ = deadline_ns;
  }
  [[nodiscard]] bool simulated() const noexcept override { return true; }

 private:
  std::int64_t now_ = 0;
};

/// Copies chosen signals every cycle into a wait-free single-producer ring for a non-RT
/// consumer. A full ring drops the record and counts it; it never blocks the producer.
class SignalTap final : public CycleHook {
 public:
  explicit SignalTap(std::vector<SignalRef> signals, std::size_t capacity_records = 1 << 15);
  /// RT thread. Record = [cycle, time_s, values of every signal...].
  void capture(std::uint64_t cycle, std::int64_t time_ns) noexcept;
  void after_cycle(const Tick& tick) noexcept override { capture(tick.cycle, tick.time_ns); }
  /// Consumer thread: append every available record (at most `max_records`) to `out`;
  /// returns records appended.
  std::size_t drain(std::vector<double>& out, std::size_t max_records = SIZE_MAX);
  [[nodiscard]] std::size_t stride() const { return stride_; }
  [[nodiscard]] const std::vector<SignalRef>& signals() const { return signals_; }
  [[nodiscard]] std::uint64_t dropped() const { return ring_.dropped(); }
  /// Records captured and not yet drained, and how many the ring holds (either thread).
  [[nodiscard]] std::size_t queued() const noexcept { return ring_.size(); }
  [[nodiscard]] std::size_t capacity() const noexcept { return ring_.capacity(); }
  /// Column of signal i's first element within a record.
  [[nodiscard]] std::size_t column(std::size_t signal_index) const { return columns_[signal_index]; }

 private:
  std::vector<SignalRef> signals_;
  SignalSpans spans_;
  std::vector<std::size_t> columns_;
  std::size_t stride_ = 2;
  SampleRing ring_;  ///< values of every signal per cycle; the header carries cycle and time
};

struct RunStats {
  std::atomic<std::uint64_t> cycles{0};          ///< cycle number reached (skipped periods included)
  std::atomic<std::uint64_t> executed{0};        ///< cycles actually run
  std::atomic<std::uint64_t> overruns{0};       ///< cycles that ended after the next deadline
  std::atomic<std::uint64_t> missed_periods{0};  ///< periods skipped under overrun_policy skip
  std::atomic<std::int64_t> last_time_ns{0};
  /// Cycle numbers of the last kOverrunLog overruns (a ring indexed by overrun count - 1), so
  /// that overruns can be attributed afterwards, e.g. to hot-swap exchange cycles.
  static constexpr std::size_t kOverrunLog = 4096;
  std::array<std::atomic<std::uint64_t>, kOverrunLog> overrun_cycles{};
  /// The logged overrun cycles, oldest first (at most kOverrunLog). Not for the RT thread.
  [[nodiscard]] std::vector<std::uint64_t> logged_overruns() const;
  Histogram wake_latency;  ///< actual wake-up minus deadline (real clock only)
  Histogram cycle_time;    ///< whole cycle execution time
};

struct RunResult {
  bool faulted = false;
  std::string fault;  ///< "block: reason"
  bool stopped_by_request = false;
  double wall_s = 0.0;
  std::vector<std::string> warnings;  ///< RT settings the host refused, etc.
};

class Scheduler {
 public:
  Scheduler(Pipeline& pipeline, Clock& clock, EventLog& events);

  /// Called on the RT thread around every cycle (taps, telemetry, the command mailbox).
  /// Add every hook before run(); the list is fixed while running.
  void add_hook(CycleHook* hook) { hooks_.push_back(hook); }
  void add_tap(SignalTap* tap) { add_hook(tap); }
  /// Measure per-op execution time (two clock reads per op).
  void set_time_ops(bool on) { time_ops_ = on; }
  /// On the simulated clock, measure the ops of one cycle in `n` only (default 1: every
  /// cycle); the real clock always measures every cycle.
  void set_simulated_timing_stride(std::uint64_t n) { simulated_timing_stride_ = n > 0 ? n : 1; }

  /// On the simulated clock, run only these cycle numbers (ascending), each with the time of
  /// its period, as a recording's real-time loop ran them: with `overrun_policy: skip` a late
  /// cycle's successors skip the periods already lost, and a replay must give every block the
  /// same ticks to compute the same outputs. `cycles` in run() then bounds the cycle numbers,
  /// as it does on the real clock. Empty (the default): every cycle.
  void follow_cycles(std::vector<std::uint64_t> cycle_numbers) { followed_cycles_ = std::move(cycle_numbers); }

  /// Run `cycles` cycles (0 = until `stop` is set). `on_idle` runs on the calling thread,
  /// never on the RT thread. The pipeline must be active.
  RunResult run(std::uint64_t cycles, const std::atomic<bool>& stop,
                const std::function<void()>& on_idle);

  [[nodiscard]] const RunStats& stats() const { return stats_; }

  /// From a thread other than the RT one (a service that found the run cannot go on, such as a
  /// recording that must not lose data): end the run as a fault with `reason`. The RT thread
  /// drives the outputs safe before its next cycle; the first reason given is kept.
  void request_fault(std::string reason);

 private:
  RunResult run_simulated(std::uint64_t cycles, const std::atomic<bool>& stop,
                          const std::function<void()>& on_idle);
  RunResult run_real(std::uint64_t cycles, const std::atomic<bool>& stop,
                     const std::function<void()>& on_idle);
  /// One cycle; false on fault (result filled).
  /// `simulated`: the clock's simulated(), asked once per run, not per cycle.
  bool cycle(const Tick& tick, bool simulated, RunResult& result) noexcept;

  Pipeline& pipeline_;
  Clock& clock_;
  EventLog& events_;
  std::vector<CycleHook*> hooks_;
  bool time_ops_ = true;
  std::uint64_t simulated_timing_stride_ = 1;
  std::vector<std::uint64_t> followed_cycles_;
  RunStats stats_;
  // Fault details written by the RT thread, read after it joins.
  int fault_op_ = -1;
  const char* fault_reason_ = nullptr;
  bool fault_envelope_ = false;
  // request_fault(): the flag is all the RT thread reads; the text is read after it joins.
  std::atomic<bool> fault_requested_{false};
  std::mutex requested_fault_mutex_;
  std::string requested_fault_;
};

}  // namespace lode
