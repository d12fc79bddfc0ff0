// Whether a subscriber's samples of one topic are all there: what `lode record` and `lode echo`
// say about missing samples.
//
// A step in the cycle number between two samples does not by itself mean something was lost.
// A real-time loop with `overrun_policy: skip` leaves out the periods after an overrun, and
// publishes nothing for them. What the subscriber can tell apart:
//   - the DDS writer numbers its samples 1, 2, 3, ...: a step there is a sample that was sent
//     and never arrived (lost on the way, or dropped by a reader's full history);
//   - a step in the cycle with none in that number is a sample never sent: the loop skipped
//     those cycles, or the pipeline's telemetry could not hand the sample over (its rings
//     were full, or the write failed). The pipeline counts the latter in its timing topic
//     (`telemetry_dropped`, cumulative over the run): a gap between two timing reports that
//     show the same count is a skipped period, and nothing was lost.
// A gap that cannot be placed that way (no timing report after it, the count rose, too many
// gaps to keep) counts as missing: unsure is never reported as complete.
#pragma once

#include <cstdint>
#include <vector>

namespace lode::cli {

/// One topic's samples from one pipeline, as they arrive (one thread).
class SampleContinuity {
 public:
  /// At most this many never-sent gaps are kept for classify(); later ones count as missing.
  static constexpr std::size_t kMaxUnsentGaps = 1 << 16;

  explicit SampleContinuity(std::uint32_t decimation) : decimation_(decimation == 0 ? 1 : decimation) {}

  /// One sample: its writer (0: unknown), that writer's sequence number (0: unknown, then a
  /// step in the cycle counts as lost) and its cycle.
  void add(std::uint64_t writer, std::uint64_t sequence, std::uint64_t cycle);

  /// A report of the pipeline's timing topic: at `cycle`, `telemetry_dropped` samples had not
  /// been handed over since the run began. Reports arrive in cycle order; one with a lower
  /// cycle starts a new run (the history before it is forgotten).
  void timing(std::uint64_t cycle, std::uint64_t telemetry_dropped);
  /// Whether a timing report at or after `cycle` has come (classify() can place every gap
  /// before it).
  [[nodiscard]] bool timing_reaches(std::uint64_t cycle) const;
  /// The cycle of the last sample (0 before the first).
  [[nodiscard]] std::uint64_t last_cycle() const { return last_cycle_; }
  /// How many writers sent samples: more than one is a pipeline restarted, or a namesake.
  [[nodiscard]] std::uint64_t writers() const { return writers_seen_; }

  [[nodiscard]] std::uint64_t received() const { return received_; }
  /// Samples sent and never received (steps in a writer's sequence numbers).
  [[nodiscard]] std::uint64_t lost() const { return lost_; }
  /// Samples due by the cycle count that were never sent, whatever the reason.
  [[nodiscard]] std::uint64_t unsent() const { return unsent_; }
  /// Samples whose cycle was not after the newest one (duplicates, reordering, a namesake).
  [[nodiscard]] std::uint64_t out_of_order() const { return out_of_order_; }

  struct Verdict {
    std::uint64_t missing = 0;  ///< lost, plus unsent samples not shown to be skipped periods
    std::uint64_t skipped = 0;  ///< unsent because the loop skipped their cycles
  };
  /// Every gap placed with the timing reports seen so far.
  [[nodiscard]] Verdict classify() const;

 private:
  struct WriterState {
    std::uint64_t writer = 0, sequence = 0, cycle = 0;
  };
  struct UnsentGap {
    std::uint64_t after_cycle = 0, before_cycle = 0;  ///< the samples either side
    std::uint64_t samples = 0;
  };
  struct TimingReport {
    std::uint64_t cycle = 0, telemetry_dropped = 0;
  };

  std::uint32_t decimation_;
  std::vector<WriterState> writers_;  ///< one per writer seen (a restarted pipeline is a new one)
  std::vector<UnsentGap> unsent_gaps_;
  std::vector<TimingReport> timing_;  ///< only the reports where the count changed, and the last
  std::uint64_t received_ = 0, lost_ = 0, out_of_order_ = 0, unsent_unplaced_ = 0;
  std::uint64_t unsent_ = 0;  ///< every never-sent sample, placed or not
  std::uint64_t last_cycle_ = 0;
  std::uint64_t writers_seen_ = 0;
};

}  // namespace lode::cli
