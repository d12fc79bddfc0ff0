// The timing of a run as one JSON document, stored with its recording (root attribute
// `timing`) so that `lode plot` can show what the end-of-run summary shows: wake-up latency
// and per-block execution-time histograms, and when the overruns happened.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "lode/sdk/histogram.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"

namespace lode::cli {

/// The non-empty bins of `histogram`, lowest first, as (upper edge in ns, count); the bin
/// holding the maximum has the maximum as its edge.
std::vector<std::pair<std::int64_t, std::uint64_t>> histogram_bins(const Histogram& histogram);

/// {count, min_ns, max_ns, mean_ns, summary_us (as the run summary prints it),
///  upper_edge_ns: [...], count_per_bin: [...]}.
Json histogram_json(const Histogram& histogram);

/// Cycles, overruns (and the cycles of the last RunStats::kOverrunLog of them), the
/// wake-up latency and whole-cycle histograms, and each op's execution-time histogram.
/// Reads the statistics of the run so far: call it off the RT thread.
Json run_timing_json(const Pipeline& pipeline, const RunStats& stats);

}  // namespace lode::cli
