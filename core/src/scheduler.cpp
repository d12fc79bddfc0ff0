#include "lode/scheduler.hpp"

#include <pthread.h>
#include <time.h>

#include <cerrno>
#include <cstring>
#include <chrono>
#include <fstream>
#include <thread>

#include "lode/crash_guard.hpp"
#include "lode/realtime.hpp"
#include "lode/sdk/rt_log.hpp"

namespace lode {

std::int64_t RealClock::now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void RealClock::sleep_until(std::int64_t deadline_ns) noexcept {
  const std::int64_t wake_ns = deadline_ns - spin_ns_;
  if (spin_ns_ <= 0 || now_ns() < wake_ns) {
    timespec ts{};
    ts.tv_sec = wake_ns / 1'000'000'000;
    ts.tv_nsec = wake_ns % 1'000'000'000;
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
  while (spin_ns_ > 0 && now_ns() < deadline_ns) cpu_relax();
}

// --------------------------------------------------------------------------------------

namespace {
std::size_t total_size(const std::vector<SignalRef>& signals) {
  std::size_t n = 0;
  for (const auto& s : signals) n += s.size();
  return n;
}
}  // namespace

SignalTap::SignalTap(std::vector<SignalRef> signals, std::size_t capacity_records)
    : signals_(std::move(signals)), spans_(signals_), ring_(total_size(signals_), capacity_records) {
  for (const auto& s : signals_) {
    columns_.push_back(stride_);
    stride_ += s.size();
  }
}

void SignalTap::capture(std::uint64_t cycle, std::int64_t time_ns) noexcept {
  double* values = ring_.claim();
  if (values == nullptr) return;  // full: counted by the ring
  spans_.copy_to(values);
  SampleHeader header;
  header.cycle = cycle;
  header.stamp_ns = time_ns;
  ring_.publish(header);
}

std::size_t SignalTap::drain(std::vector<double>& out, std::size_t max_records) {
  std::size_t n = 0;
  SampleHeader header;
  while (n < max_records) {
    const double* values = ring_.front(header);
    if (values == nullptr) break;
    out.push_back(static_cast<double>(header.cycle));
    out.push_back(static_cast<double>(header.stamp_ns) * 1e-9);
    out.insert(out.end(), values, values + (stride_ - 2));
    ring_.pop();
    ++n;
  }
  return n;
}

// --------------------------------------------------------------------------------------

Scheduler::Scheduler(Pipeline& pipeline, Clock& clock, EventLog& events)
    : pipeline_(pipeline), clock_(clock), events_(events) {}

// Inlined into both loops: on the simulated clock, a call per cycle (saving and restoring its
// registers) was a measurable share of the framework's own instructions.
[[gnu::always_inline]] inline bool Scheduler::cycle(const Tick& tick, bool simulated, RunResult& result) noexcept {
  rt_log_set_clock(tick.time_ns, tick.cycle);
  const std::int64_t start = simulated ? 0 : clock_.now_ns();
  for (auto* hook : hooks_) hook->before_cycle(tick);
  // Two clock reads per op are ~20 % of a kawato_planar cycle; on the simulated clock no
  // deadline depends on them, and the caller may sample (set_simulated_timing_stride).
  const bool time_ops = time_ops_ && (!simulated || tick.cycle % simulated_timing_stride_ == 0);
  const auto r = pipeline_.run_cycle(tick, time_ops);
  for (auto* hook : hooks_) hook->after_cycle(tick);
  // Every output and every copy of it is in place: wake whoever publishes them (a futex
  // word; see PublishDoorbell), before the statistics and the sleep.
  for (auto* hook : hooks_) hook->cycle_finished();
  if (!simulated) stats_.cycle_time.record(clock_.now_ns() - start);
  stats_.cycles.store(tick.cycle + 1, std::memory_order_relaxed);
  stats_.executed.store(stats_.executed.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  stats_.last_time_ns.store(tick.time_ns, std::memory_order_relaxed);
  if (r.status != StepStatus::ok) {
    result.faulted = true;
    fault_op_ = r.failed_op;
    fault_reason_ = r.reason;
    fault_envelope_ = r.envelope;
    return false;
  }
  return true;
}

std::vector<std::uint64_t> RunStats::logged_overruns() const {
  const std::uint64_t n = overruns.load(std::memory_order_acquire);
  std::vector<std::uint64_t> out;
  for (std::uint64_t i = n > kOverrunLog ? n - kOverrunLog : 0; i < n; ++i)
    out.push_back(overrun_cycles[i % kOverrunLog].load(std::memory_order_relaxed));
  return out;
}

void Scheduler::request_fault(std::string reason) {
  {
    std::lock_guard lock(requested_fault_mutex_);
    if (!requested_fault_.empty()) return;
    requested_fault_ = std::move(reason);
  }
  fault_requested_.store(true, std::memory_order_release);
}

RunResult Scheduler::run(std::uint64_t cycles, const std::atomic<bool>& stop,
                         const std::function<void()>& on_idle) {
  const auto wall_start = std::chrono::steady_clock::now();
  RunResult result = clock_.simulated() ? run_simulated(cycles, stop, on_idle)
                                        : run_real(cycles, stop, on_idle);
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const auto cycle = stats_.cycles.load();
  const auto t = stats_.last_time_ns.load();
  if (!result.faulted && fault_requested_.load(std::memory_order_acquire)) {
    std::lock_guard lock(requested_fault_mutex_);
    result.faulted = true;
    result.stopped_by_request = false;
    result.fault = requested_fault_;
  }
  if (result.faulted && fault_envelope_ && result.fault.empty()) result.fault = pipeline_.envelope_violation();
  if (result.faulted && fault_op_ >= 0) {
    const auto& op = pipeline_.ops()[static_cast<std::size_t>(fault_op_)];
    if (result.fault.empty())
      result.fault = op.label + ": " + (fault_reason_ ? std::string("health monitor: ") + fault_reason_
                                                      : std::string(op.block->fault_reason()));
  }
  if (result.faulted) events_.post(t, cycle, "fault", result.fault + " (outputs driven safe)");
  if (on_idle) on_idle();  // final drain
  return result;
}

RunResult Scheduler::run_simulated(std::uint64_t cycles, const std::atomic<bool>& stop,
                                   const std::function<void()>& on_idle) {
  RunResult result;
  const std::int64_t period = pipeline_.period_ns();
  Tick tick;
  tick.dt_s = 1.0 / pipeline_.rate_hz();
  // One loop for both: every cycle, or the followed ones (a constant per instantiation, so the
  // usual case pays nothing for the other).
  const auto loop = [&]<bool kFollow>() {
    const std::uint64_t runs = kFollow ? followed_cycles_.size() : cycles;
    for (std::uint64_t k = 0; runs == 0 || k < runs; ++k) {
      if (fault_requested_.load(std::memory_order_relaxed)) {
        pipeline_.drive_safe();
        break;
      }
      if (stop.load(std::memory_order_relaxed)) {
        result.stopped_by_request = true;
        break;
      }
      tick.cycle = kFollow ? followed_cycles_[k] : k;
      if (kFollow && cycles != 0 && tick.cycle >= cycles) break;
      tick.time_ns = static_cast<std::int64_t>(tick.cycle) * period;
      clock_.sleep_until(tick.time_ns);
      if (!cycle(tick, true, result)) break;
      // Drain often enough that no tap can overflow: a simulated run is never lossy.
      if ((k & 1023) == 1023 && on_idle) on_idle();
    }
  };
  if (followed_cycles_.empty())
    loop.operator()<false>();
  else
    loop.operator()<true>();
  return result;
}

RunResult Scheduler::run_real(std::uint64_t cycles, const std::atomic<bool>& stop,
                              const std::function<void()>& on_idle) {
  RunResult result;
  const RealtimeSettings& rts = pipeline_.realtime();
  result.warnings = apply_process_realtime(rts);
  if (rts.priority > 0 && rts.spin_us * 1000 >= pipeline_.period_ns()) {
    // Never sleeping, a SCHED_FIFO thread meets the kernel's RT throttling: it is stopped for
    // (period - runtime) of every sched_rt_period_us (measured: 50 ms a second, ~10000 lost
    // periods in 40 s at 5 kHz).
    std::ifstream runtime_file("/proc/sys/kernel/sched_rt_runtime_us");
    long long runtime_us = 0;
    if (runtime_file >> runtime_us && runtime_us >= 0)
      result.warnings.push_back("realtime.spin_us (" + std::to_string(rts.spin_us) +
                                " us) >= the period: the RT thread never sleeps, and the kernel's RT throttling "
                                "(kernel.sched_rt_runtime_us = " + std::to_string(runtime_us) +
                                ") will stop it for part of every second; lower spin_us or set "
                                "kernel.sched_rt_runtime_us = -1");
  }
  std::atomic<bool> done{false};
  std::vector<std::string> thread_warnings;

  std::thread rt([&] {
    pthread_setname_np(pthread_self(), "lode-rt");
    const AlternateSignalStack crash_stack;  // a stack overflow here still reaches CrashGuard
    thread_warnings = apply_thread_realtime(rts);
    const std::int64_t period = pipeline_.period_ns();
    Tick tick;
    tick.dt_s = 1.0 / pipeline_.rate_hz();
    const std::int64_t start = clock_.now_ns() + period;  // first deadline one period out
    std::int64_t deadline = start;
    std::uint64_t k = 0;
    std::uint64_t overruns = 0;
    bool overrun_stop = false;
    while ((cycles == 0 || k < cycles) && !stop.load(std::memory_order_relaxed)) {
      if (fault_requested_.load(std::memory_order_relaxed)) {
        pipeline_.drive_safe();
        break;
      }
      clock_.sleep_until(deadline);
      const std::int64_t woke = clock_.now_ns();
      stats_.wake_latency.record(woke - deadline);
      tick.cycle = k;
      tick.time_ns = deadline - start;
      if (!cycle(tick, false, result)) break;
      ++k;
      deadline += period;
      const std::int64_t now = clock_.now_ns();
      if (now > deadline) {  // this cycle ran into the next period
        stats_.overrun_cycles[overruns % RunStats::kOverrunLog].store(k, std::memory_order_relaxed);
        ++overruns;
        stats_.overruns.store(overruns, std::memory_order_relaxed);
        if (rts.overrun_policy == OverrunPolicy::stop ||
            (rts.max_overruns > 0 && overruns >= rts.max_overruns)) {
          pipeline_.drive_safe();
          overrun_stop = true;  // the message is built after the loop: no allocation here
          break;
        }
        if (rts.overrun_policy == OverrunPolicy::skip) {
          // Keep the phase of the grid: skip the periods already lost.
          const std::int64_t missed = (now - deadline) / period + 1;
          deadline += missed * period;
          k += static_cast<std::uint64_t>(missed);
          stats_.missed_periods.fetch_add(static_cast<std::uint64_t>(missed), std::memory_order_relaxed);
        }
      }
    }
    if (overrun_stop) {
      result.faulted = true;
      result.fault = "scheduler: overrun limit reached (" + std::to_string(overruns) + " overruns)";
    }
    done.store(true, std::memory_order_release);
  });
  while (!done.load(std::memory_order_acquire)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (on_idle) on_idle();
  }
  rt.join();
  release_process_realtime();
  if (stop.load() && !result.faulted && !fault_requested_.load()) result.stopped_by_request = true;
  result.warnings.insert(result.warnings.end(), thread_warnings.begin(), thread_warnings.end());
  for (const auto& w : result.warnings) events_.post(0, 0, "warning", w);
  return result;
}

}  // namespace lode
