#include "sample_continuity.hpp"

#include <algorithm>

namespace lode::cli {

namespace {
/// More writers than this on one topic (a pipeline restarted hundreds of times while one
/// subscriber stays): the oldest is forgotten.
constexpr std::size_t kMaxWriters = 64;
/// Timing reports kept: two per change of the dropped count, so this is reached only by a
/// pipeline that keeps dropping; then gaps are no longer placed (they count as missing).
constexpr std::size_t kMaxTimingReports = 1 << 18;
}  // namespace

void SampleContinuity::add(std::uint64_t writer, std::uint64_t sequence, std::uint64_t cycle) {
  ++received_;
  auto it = std::find_if(writers_.begin(), writers_.end(), [writer](const WriterState& w) { return w.writer == writer; });
  if (it == writers_.end()) {
    if (writers_.size() == kMaxWriters) writers_.erase(writers_.begin());
    writers_.push_back({writer, sequence, cycle});
    ++writers_seen_;
    last_cycle_ = cycle;
    return;
  }
  WriterState& state = *it;
  const bool numbered = sequence != 0 && state.sequence != 0;
  if (numbered ? sequence <= state.sequence : cycle <= state.cycle) {
    ++out_of_order_;
    return;
  }
  std::uint64_t lost_here = 0;
  if (numbered) {
    lost_here = sequence - state.sequence - 1;
    lost_ += lost_here;
  }
  if (cycle > state.cycle) {
    // ceil(step / decimation) - 1 samples were due in between.
    const std::uint64_t due = (cycle - state.cycle + decimation_ - 1) / decimation_ - 1;
    if (!numbered) {
      lost_ += due;
    } else if (due > lost_here) {
      unsent_ += due - lost_here;
      if (unsent_gaps_.size() < kMaxUnsentGaps) unsent_gaps_.push_back({state.cycle, cycle, due - lost_here});
      else unsent_unplaced_ += due - lost_here;
    }
    state.cycle = cycle;
  } else {
    ++out_of_order_;  // a newer sample of an older cycle: the writer's numbering and its cycles disagree
  }
  state.sequence = sequence;
  last_cycle_ = state.cycle;
}

void SampleContinuity::timing(std::uint64_t cycle, std::uint64_t telemetry_dropped) {
  if (!timing_.empty() && cycle < timing_.back().cycle) {
    // A new run: the gaps kept so far belong to the old one, whose reports are gone.
    for (const UnsentGap& g : unsent_gaps_) unsent_unplaced_ += g.samples;
    unsent_gaps_.clear();
    timing_.clear();
  }
  // A run of equal counts is kept as its first and last report.
  const std::size_t n = timing_.size();
  if (n >= 2 && timing_[n - 1].telemetry_dropped == telemetry_dropped &&
      timing_[n - 2].telemetry_dropped == telemetry_dropped) {
    timing_.back().cycle = cycle;
  } else if (n < kMaxTimingReports) {
    timing_.push_back({cycle, telemetry_dropped});
  }
}

bool SampleContinuity::timing_reaches(std::uint64_t cycle) const {
  return !timing_.empty() && timing_.back().cycle >= cycle;
}

SampleContinuity::Verdict SampleContinuity::classify() const {
  Verdict v;
  v.missing = lost_ + unsent_unplaced_;
  for (const UnsentGap& g : unsent_gaps_) {
    // The count before the gap: the last report at or before it (0 before the first report,
    // since the count starts with the run); after it: the first report at or after it.
    const auto after = std::lower_bound(timing_.begin(), timing_.end(), g.before_cycle,
                                        [](const TimingReport& r, std::uint64_t c) { return r.cycle < c; });
    const auto before = std::upper_bound(timing_.begin(), timing_.end(), g.after_cycle,
                                         [](std::uint64_t c, const TimingReport& r) { return c < r.cycle; });
    const std::uint64_t dropped_before = before == timing_.begin() ? 0 : std::prev(before)->telemetry_dropped;
    if (after != timing_.end() && after->telemetry_dropped == dropped_before) v.skipped += g.samples;
    else v.missing += g.samples;
  }
  return v;
}

}  // namespace lode::cli
