// `lode rtcheck --latency`: the wake-up latency of a periodic SCHED_FIFO thread on the RT CPU,
// measured like cyclictest (an absolute clock_nanosleep loop on CLOCK_MONOTONIC, latency =
// actual wake-up - intended), and the headroom it leaves the pipeline's cycle.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "host_checks.hpp"
#include "lode/pipeline.hpp"
#include "lode/sdk/histogram.hpp"

namespace lode::cli {

/// "10s", "500ms", "2m" or a bare number of seconds, more than 0 and at most a day; nullopt
/// with `why` set when it is none of these.
std::optional<std::int64_t> parse_duration_ns(const std::string& text, std::string& why);

struct LatencyPlan {
  int cpu = -1;       ///< -1: not pinned
  int priority = 80;  ///< SCHED_FIFO; 0: normal scheduling
  std::int64_t period_ns = 1'000'000;
  std::int64_t duration_ns = 10'000'000'000;
  /// When set, its cycle is run back to back first (as `lode bench` does) for its cost.
  Pipeline* pipeline = nullptr;
  /// Why the cycle is not timed although there is a pipeline ("" = it is, when `pipeline` is set).
  std::string cycle_cost_skipped;
  std::uint64_t cost_cycles = 5000;
};

struct LatencyReport {
  LatencyPlan plan;
  std::unique_ptr<Histogram> wakeups = std::make_unique<Histogram>();
  std::unique_ptr<Histogram> cycle_cost;  ///< null without a pipeline
  std::string cycle_cost_error;           ///< why the pipeline's cycle could not be timed
  bool sched_fifo = false;                ///< the thread ran SCHED_FIFO at plan.priority
  bool pinned = false;                    ///< the thread ran on plan.cpu only
  bool interrupted = false;               ///< stopped early by SIGINT/SIGTERM
  std::uint64_t missed_periods = 0;       ///< deadlines skipped because a wake-up came after them
  std::vector<std::string> setup_warnings;  ///< mlockall, SCHED_FIFO or affinity refused
  [[nodiscard]] std::int64_t headroom_ns() const;
};

/// Locks memory, starts the measuring thread with the plan's CPU and priority, times the
/// pipeline's cycle (if any), then runs the wake-up loop for the plan's duration. Whatever is
/// refused (SCHED_FIFO, the CPU) is noted and the measurement runs anyway.
LatencyReport measure_latency(const LatencyPlan& plan);

/// The findings as checks: "latency_setup" (WARN when the conditions were not the pipeline's)
/// and "headroom" (FAIL when the worst wake-up plus the cycle's p99 exceeds the period).
std::vector<CheckResult> latency_checks(const LatencyReport& report);
/// count, min, p50, p90, p99, p99.9, max in microseconds, the histogram and the headroom.
Json latency_json(const LatencyReport& report);
std::string latency_text(const LatencyReport& report);

}  // namespace lode::cli
