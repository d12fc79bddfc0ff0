#include "run_timing.hpp"

namespace lode::cli {

std::vector<std::pair<std::int64_t, std::uint64_t>> histogram_bins(const Histogram& histogram) {
  std::vector<std::pair<std::int64_t, std::uint64_t>> bins;
  histogram.for_each_bin([&](std::int64_t edge, std::uint64_t count) { bins.emplace_back(edge, count); });
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
