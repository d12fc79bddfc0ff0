#include "run_timing.hpp"

namespace lode::cli {

// Histogram keeps its bin counts private and offers only percentile(q), the upper edge of
// the bin holding rank floor(q * (n - 1)) + 1. The count of each bin is recovered exactly from
// that: the ranks sharing an edge are one bin, and the last rank of each is found by
// bisection (at most 1184 bins x log2(n) queries, a few milliseconds at the end of a run).
std::vector<std::pair<std::int64_t, std::uint64_t>> histogram_bins(const Histogram& histogram) {
  std::vector<std::pair<std::int64_t, std::uint64_t>> bins;
  const std::uint64_t n = histogram.count();
  if (n == 0) return bins;
  if (n == 1) return {{histogram.max(), 1}};
  // The quantile whose target rank is exactly r (1-based): halfway between two ranks.
  const auto edge_of_rank = [&](std::uint64_t r) {
    return histogram.percentile((static_cast<double>(r) - 0.5) / static_cast<double>(n - 1));
  };
  std::uint64_t first = 1;
  while (first <= n) {
    const std::int64_t edge = edge_of_rank(first);
    std::uint64_t lo = first, hi = n;  // the last rank with this edge lies in [lo, hi]
    while (lo < hi) {
      const std::uint64_t mid = lo + (hi - lo + 1) / 2;
      if (edge_of_rank(mid) == edge) lo = mid;
      else hi = mid - 1;
    }
    bins.emplace_back(edge, lo - first + 1);
    first = lo + 1;
  }
  return bins;
}

Json histogram_json(const Histogram& histogram) {
  Json j = Json::object();
  j["count"] = histogram.count();
  j["min_ns"] = histogram.min();
  j["max_ns"] = histogram.max();
  j["mean_ns"] = histogram.mean();
  j["summary_us"] = histogram.summary_us();
  Json edges = Json::array();
  Json counts = Json::array();
  for (const auto& [edge, count] : histogram_bins(histogram)) {
    edges.push(edge);
    counts.push(count);
  }
  j["upper_edge_ns"] = std::move(edges);
  j["count_per_bin"] = std::move(counts);
  return j;
}

Json run_timing_json(const Pipeline& pipeline, const RunStats& stats) {
  Json j = Json::object();
  j["rate_hz"] = pipeline.rate_hz();
  j["cycles"] = stats.cycles.load();
  j["executed"] = stats.executed.load();
  j["overruns"] = stats.overruns.load();
  j["missed_periods"] = stats.missed_periods.load();
  Json overrun_cycles = Json::array();
  for (const auto cycle : stats.logged_overruns()) overrun_cycles.push(cycle);
  j["overrun_cycles"] = std::move(overrun_cycles);
  j["overrun_log_capacity"] = static_cast<std::uint64_t>(RunStats::kOverrunLog);
  // Only the real clock wakes up: on the simulated clock this histogram is empty.
  j["wake_latency"] = histogram_json(stats.wake_latency);
  j["cycle_time"] = histogram_json(stats.cycle_time);
  Json blocks = Json::object();
  for (const auto& op : pipeline.ops()) blocks[op.label] = histogram_json(*op.exec_time);
  j["block_exec_time"] = std::move(blocks);
  return j;
}

}  // namespace lode::cli
