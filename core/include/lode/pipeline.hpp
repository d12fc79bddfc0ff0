// A pipeline: blocks loaded from plugins, wired by name, ordered, with one output arena.
//
// Loading validates everything before anything starts and collects every problem with its
// file:line:column (Diagnostics). The cycle (run_cycle) walks a precomputed list of
// operations: every io block's read phase, the other blocks in topological order, then
// every io block's write phase.
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/diagnostics.hpp"
#include "lode/sdk/histogram.hpp"
#include "lode/sdk/json.hpp"
#include "lode/plugin_loader.hpp"

namespace lode {

namespace pipeline_detail {
class Roles;
}  // namespace pipeline_detail

struct TelemetrySpec;  // telemetry.hpp

enum class OverrunPolicy { skip, catch_up, stop };

struct RealtimeSettings {
  int priority = 0;          ///< SCHED_FIFO priority 1..99; 0 = normal scheduling
  int cpu = -1;              ///< CPU to pin the RT thread to; -1 = any
  bool lock_memory = false;  ///< mlockall + prefault
  OverrunPolicy overrun_policy = OverrunPolicy::skip;
  std::uint64_t max_overruns = 0;  ///< stop with a fault after this many; 0 = never
  /// Sleep until this long before each deadline, then busy-wait to it (0 = sleep all the way).
  /// On hosts whose idle CPUs lose their caches or wake slowly (VMs, deep C-states) this cuts
  /// wake-up latency and keeps the cycle's data cached, at the price of a busier CPU.
  std::int64_t spin_us = 0;
  /// The clock `lode run` uses unless --clock says: simulated (as fast as the host computes)
  /// or real (periodic on CLOCK_MONOTONIC). Pipelines with hardware boards say real.
  bool real_clock = false;
};

/// How `lode run --record` treats its file (the `record:` section).
struct RecordSettings {
  /// Wall-clock time between two flushes of the recording to the file: a crash (SIGKILL, power
  /// cut after the OS wrote its cache) loses at most this much of the run.
  double flush_interval_s = 1.0;
  /// What a failing recording (disk full, I/O error) does to the run: the recorder always
  /// stops cleanly and says what it kept; with `stop` the run also faults (outputs safe).
  bool stop_on_error = false;
};

/// Why `name` cannot name a pipeline, or "" when it can. The name becomes a file name (the
/// local command socket) and part of DDS participant and topic names, so it is held to
/// letters, digits, '_', '-' and '.', not starting with '.' or '-', at most 64 characters:
/// `../../evil` must not reach outside the runtime directory.
std::string pipeline_name_problem(const std::string& name);

struct SignalRef {
  std::string block;
  std::string port;
  const double* data = nullptr;
  const Elements* elements = nullptr;
  [[nodiscard]] std::size_t size() const { return elements ? elements->size() : 0; }
  [[nodiscard]] std::string name() const { return block + "." + port; }
};

/// A list of signals as runs of adjacent storage (the outputs of one block, of blocks next to
/// each other in the pipeline's arena), for the hooks that take every signal's values each
/// cycle: one copy per run instead of one per signal, none when they are all one run.
class SignalSpans {
 public:
  explicit SignalSpans(const std::vector<SignalRef>& signals) {
    for (const auto& s : signals) {
      if (s.size() == 0) continue;
      values_ += s.size();
      if (!spans_.empty() && spans_.back().data + spans_.back().size == s.data)
        spans_.back().size += s.size();
      else
        spans_.push_back({s.data, s.size()});
    }
  }
  /// Every signal's values, in the order given, to `out` (room for values()); past the last.
  double* copy_to(double* out) const noexcept {
    for (const Span& s : spans_) {
      std::memcpy(out, s.data, s.size * sizeof(double));
      out += s.size;
    }
    return out;
  }
  /// Where the values are when all the signals are one run in the order given, else nullptr.
  [[nodiscard]] const double* contiguous() const noexcept {
    return spans_.size() == 1 ? spans_.front().data : nullptr;
  }
  [[nodiscard]] std::size_t values() const noexcept { return values_; }

 private:
  struct Span {
    const double* data;
    std::size_t size;
  };
  std::vector<Span> spans_;
  std::size_t values_ = 0;
};

/// What `lode run` shows live and analyses at the end (the `monitor:` section).
struct MonitorSpec {
  std::optional<SignalRef> show;       ///< live status line
  std::optional<SignalRef> estimate;   ///< what the controllers see
  std::optional<SignalRef> truth;      ///< the true state (simulation)
  std::optional<SignalRef> reference;  ///< the commanded trajectory
  std::vector<SignalRef> record;       ///< extra signals kept for the summary
  double hold_start_s = 0.0;           ///< window for the position-noise statistics
  double hold_end_s = 0.0;
  double settle_band = 0.02;           ///< settling band, fraction of the step
};

class Pipeline {
 public:
  struct Op {
    Block* block = nullptr;
    Board* board = nullptr;  ///< the io block's board interface: its write phase
    std::string label;  ///< "glsdc" or "stage.read" / "stage.write"
    bool write_phase = false;
    std::unique_ptr<Histogram> exec_time;
    int family = -1;  ///< internal: the swappable role this op steps (-1 for io blocks)
  };

  struct CycleResult {
    StepStatus status = StepStatus::ok;
    int failed_op = -1;            ///< index into ops() when status is fault
    const char* reason = nullptr;  ///< set when the health monitor faulted the cycle (else ask the block)
    bool envelope = false;         ///< the envelope faulted the cycle: see envelope_violation()
  };

  /// A health-monitor trip (`health:` section), taken off the RT thread by whoever posts events.
  struct HealthTrip {
    std::uint64_t cycle = 0;
    std::int64_t time_ns = 0;
    std::string block;            ///< the monitored primary
    std::string reason;           ///< e.g. "non-finite output"
    std::string fallback;         ///< the shadow that took over in the same cycle ("" = outputs driven safe)
    std::string fallback_plugin;
    std::uint64_t lost = 0;       ///< > 0: this many trips were lost (ring full); other fields empty
  };

  /// Load, configure and bind. Returns nullptr when diagnostics is not empty.
  static std::unique_ptr<Pipeline> load_file(const std::string& path, PluginRegistry& registry,
                                             Diagnostics& diagnostics);
  /// `feeds` (test support): outputs of a pseudo-block named "feed" whose values the caller
  /// writes through signal("feed.<name>"), so a block under test is wired like any other.
  static std::unique_ptr<Pipeline> load_text(const std::string& yaml, const std::string& label,
                                             PluginRegistry& registry, Diagnostics& diagnostics,
                                             const std::vector<std::pair<std::string, Elements>>& feeds = {});

  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  [[nodiscard]] const std::string& name() const;
  [[nodiscard]] const std::string& source_file() const;
  [[nodiscard]] double rate_hz() const;
  [[nodiscard]] std::int64_t period_ns() const;
  [[nodiscard]] const RealtimeSettings& realtime() const;
  [[nodiscard]] std::optional<double> default_duration_s() const;
  [[nodiscard]] const RecordSettings& record_settings() const;
  [[nodiscard]] const MonitorSpec& monitor() const;
  /// The `telemetry:` section (enabled == false when absent). Defined in telemetry.hpp.
  [[nodiscard]] const TelemetrySpec& telemetry() const;
  /// The pipeline file's text as loaded (recorded with every recording).
  [[nodiscard]] const std::string& source_text() const;

  Status activate();
  void deactivate() noexcept;

  /// One cycle. RT-safe. When `time_ops` is set each op's execution time is recorded.
  /// On a fault every io block is driven safe before returning.
  CycleResult run_cycle(const Tick& tick, bool time_ops) noexcept;
  void drive_safe() noexcept;
  /// After a cycle the envelope faulted: which value left which limit, when (not for the RT thread).
  [[nodiscard]] std::string envelope_violation() const;
  /// The envelope's bounds on values, per limited signal: min and max per element (-inf/+inf
  /// where not bounded). Rates and invalid-time budgets are not included.
  struct EnvelopeBounds {
    SignalRef signal;
    std::vector<double> min, max;
  };
  [[nodiscard]] std::vector<EnvelopeBounds> envelope_bounds() const;

  [[nodiscard]] std::vector<Op>& ops();
  [[nodiscard]] const std::vector<Op>& ops() const;
  /// "block.port" -> the output, if it exists.
  [[nodiscard]] std::optional<SignalRef> signal(const std::string& ref) const;
  /// Every output of every block.
  [[nodiscard]] std::vector<SignalRef> signals() const;
  /// The instance now running in the role named `name` (nullptr if none). A hot swap,
  /// promotion or health fallback changes it; the pointer stays valid until the next swap
  /// of that role completes.
  [[nodiscard]] Block* block(const std::string& name) const;
  /// Address of the Block* the RT thread steps for `name` (stable for the pipeline's life).
  /// Dereference it only on the RT thread, or while no RT thread runs.
  [[nodiscard]] Block* const* block_slot(const std::string& name) const;
  /// Plugin of the instance now running in role `name`.
  [[nodiscard]] std::string plugin_of(const std::string& name) const;
  /// Trips recorded by the RT thread since the last call (single consumer).
  std::vector<HealthTrip> take_health_trips();
  /// Names of every block, in file order.
  [[nodiscard]] std::vector<std::string> block_names() const;
  /// Blocks declared with `shadow_of: <primary>`: stepped after their primary on the same
  /// inputs, outputs in their own storage.
  struct ShadowInfo {
    std::string name;     ///< the shadow's block name (its outputs are "<name>.<port>")
    std::string primary;  ///< the block it shadows
  };
  [[nodiscard]] std::vector<ShadowInfo> shadows() const;
  /// The resolved pipeline with every derived quantity.
  [[nodiscard]] Json describe() const;

  struct Impl;
  /// Roles and instances: the API through which a hot swap changes this pipeline (an
  /// internal type of the runtime; plugins and applications have no use for it).
  [[nodiscard]] pipeline_detail::Roles& roles();

 private:
  Pipeline();
  std::unique_ptr<Impl> impl_;
};

}  // namespace lode
