// A loaded pipeline run on the simulated clock by the real Scheduler, with a SignalTap on the
// signals a test checks: the trace behind the closed-loop integration tests. Each test reads
// its rows into its own Trace; this is the part they all ran the same way.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"

namespace lode::test {

/// What the tap recorded, one row per cycle: [cycle, time_s, each tapped signal's values].
struct TappedRun {
  std::vector<double> rows;
  std::size_t stride = 0;
  std::vector<std::size_t> columns;  ///< where each tapped signal's first value is in a row
  std::uint64_t dropped = 0;         ///< rows the tap's ring had no room for
  bool faulted = false;
  std::string fault;

  [[nodiscard]] std::size_t size() const { return stride == 0 ? 0 : rows.size() / stride; }
  [[nodiscard]] double time_s(std::size_t row) const { return rows[row * stride + 1]; }
  /// The values of the `signal`-th tapped signal in `row`.
  [[nodiscard]] const double* values(std::size_t row, std::size_t signal) const {
    return &rows[row * stride + columns[signal]];
  }
};

/// `cycles` cycles of the activated `pipeline` with `signals` tapped through a ring of
/// `ring_records` (drained at every idle call of the scheduler, and once more at the end).
/// `time_ops` as Scheduler::set_time_ops (off: no per-block timing in the cycle).
inline TappedRun run_tapped(Pipeline& pipeline, const std::vector<std::string>& signals, std::uint64_t cycles,
                            std::size_t ring_records, bool time_ops = true) {
  std::vector<SignalRef> refs;
  for (const auto& name : signals) refs.push_back(*pipeline.signal(name));
  SignalTap tap(refs, ring_records);
  SimulatedClock clock;
  EventLog events;
  Scheduler scheduler(pipeline, clock, events);
  scheduler.set_time_ops(time_ops);
  scheduler.add_tap(&tap);
  TappedRun run;
  run.stride = tap.stride();
  for (std::size_t i = 0; i < signals.size(); ++i) run.columns.push_back(tap.column(i));
  run.rows.reserve(static_cast<std::size_t>(cycles + 16) * run.stride);
  std::atomic<bool> stop{false};
  const auto result = scheduler.run(cycles, stop, [&] { tap.drain(run.rows); });
  tap.drain(run.rows);
  run.dropped = tap.dropped();
  run.faulted = result.faulted;
  run.fault = result.fault;
  return run;
}

}  // namespace lode::test
