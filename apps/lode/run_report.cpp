#include "run_report.hpp"

#include <cstdio>
#include <string>

#include "journal_output.hpp"
#include "lode/sdk/rt_log.hpp"

namespace lode::cli {
namespace {

Json timing_json(const RunFacts& f) {
  const Pipeline& p = f.pipeline;
  const RunResult& r = f.result;
  const bool simulated = f.simulated;
  const double sim_seconds = static_cast<double>(f.scheduler.stats().cycles.load()) / p.rate_hz();
  Json j = Json::object();
  const auto& st = f.scheduler.stats();
  j["clock"] = simulated ? "sim" : "real";
  j["cycles"] = st.cycles.load();
  j["rate_hz"] = p.rate_hz();
  j["wall_s"] = r.wall_s;
  j["scheduled_s"] = sim_seconds;  // time covered by the cycle grid
  if (simulated) {
    j["speed_vs_realtime"] = r.wall_s > 0 ? sim_seconds / r.wall_s : 0.0;
  } else {
    j["executed_cycles"] = st.executed.load();
    j["achieved_rate_hz"] = sim_seconds > 0 ? static_cast<double>(st.executed.load()) / sim_seconds : 0.0;
    j["wake_latency"] = st.wake_latency.summary_us();
    j["cycle_time"] = st.cycle_time.summary_us();
  }
  j["overruns"] = st.overruns.load();
  j["missed_periods"] = st.missed_periods.load();
  Json blocks = Json::object();
  for (const auto& op : p.ops()) blocks[op.label] = op.exec_time->summary_us();
  j["block_exec_time"] = std::move(blocks);
  return j;
}

}  // namespace

Json finish_run_summary(const RunFacts& f) {
  Json summary = Json::object();
  summary["pipeline"] = f.pipeline.name();
  summary["config"] = f.config;
  summary["result"] = f.result.faulted ? "fault" : f.result.stopped_by_request ? "stopped" : "completed";
  if (f.result.faulted) summary["fault"] = f.result.fault;
  const Json figures = f.analysis.finish();
  for (const auto& [k, v] : figures.members()) summary[k] = v;
  summary["timing"] = timing_json(f);
  summary["recording"] = Json::object();
  summary["recording"]["samples"] = f.analysis.samples();
  summary["recording"]["dropped"] = f.analysis.dropped();
  summary["rt_log_dropped"] = rt_log_ring().dropped();
  const Json service_summary = f.services.summary();
  for (const auto& [k, v] : service_summary.members()) summary[k] = v;
  summary["warnings"] = Json::array();
  for (const auto& w : f.result.warnings) summary["warnings"].push(w);
  summary["events"] = f.events.to_json();
  // The summary keeps the first and the latest events; how many fell between is said, not hidden.
  summary["events_posted"] = f.events.posted();
  summary["events_dropped"] = f.events.dropped();
  summary["events_suppressed"] = f.events.suppressed();  // refused commands beyond 10 a second
  return summary;
}

void print_run_summary(const Json& summary, const RunFacts& f) {
  const auto& st = f.scheduler.stats();
  std::FILE* const out = severity_stream(stdout, Severity::info);  // stdout itself unless it is the journal
  // Timing, human-readable.
  const auto& tj = *summary.find("timing");
  if (!f.simulated) {
    const auto& wl = *tj.find("wake_latency");
    std::fprintf(out, "  timing: %llu cycles run at %.1f Hz achieved; wake-up latency p50 %.1f us, p99 %.1f us, "
                 "p99.9 %.1f us, max %.1f us; overruns %llu, missed periods %llu\n",
                 static_cast<unsigned long long>(st.executed.load()), tj.find("achieved_rate_hz")->as_number(),
                 wl.find("p50_us")->as_number(), wl.find("p99_us")->as_number(),
                 wl.find("p999_us")->as_number(), wl.find("max_us")->as_number(),
                 static_cast<unsigned long long>(st.overruns.load()),
                 static_cast<unsigned long long>(st.missed_periods.load()));
  } else {
    std::fprintf(out, "  timing: %llu cycles simulated in %.3f s wall (%.0fx real time)\n",
                 static_cast<unsigned long long>(st.cycles.load()), f.result.wall_s,
                 tj.find("speed_vs_realtime")->as_number());
  }
  const std::uint64_t timed = f.pipeline.ops().empty() ? 0 : f.pipeline.ops().front().exec_time->count();
  std::fprintf(out, "  step cost per block (p50 / p99 / max, us; %llu of the cycles timed%s):",
               static_cast<unsigned long long>(timed), f.simulated ? ", one in 64 on the simulated clock" : "");
  for (const auto& op : f.pipeline.ops())
    std::fprintf(out, "  %s %.2f/%.2f/%.1f", op.label.c_str(), static_cast<double>(op.exec_time->percentile(0.5)) / 1e3,
                 static_cast<double>(op.exec_time->percentile(0.99)) / 1e3,
                 static_cast<double>(op.exec_time->max()) / 1e3);
  std::fprintf(out, "\n");
  if (const auto* t = summary.find("telemetry")) {
    const auto number = [&](const char* key) { return t->find(key) ? t->find(key)->as_number() : 0.0; };
    const int asked = static_cast<int>(number("publisher_priority_asked"));
    const int got = static_cast<int>(number("publisher_priority"));
    char scheduling[160];
    if (got > 0)
      std::snprintf(scheduling, sizeof scheduling, "the publisher at SCHED_FIFO %d", got);
    else if (asked > 0)
      std::snprintf(scheduling, sizeof scheduling,
                    "the publisher normally scheduled (SCHED_FIFO %d refused: see `lode rtcheck`)", asked);
    else
      std::snprintf(scheduling, sizeof scheduling, "the publisher normally scheduled");
    std::fprintf(out, "  telemetry: domain %lld, %llu samples handed over, %llu dropped by the RT side (rings full), "
                 "%llu published; %s\n",
                 static_cast<long long>(number("domain")), static_cast<unsigned long long>(number("samples_offered")),
                 static_cast<unsigned long long>(number("ring_dropped")),
                 static_cast<unsigned long long>(number("published")), scheduling);
  }
  if (const auto* t = summary.find("telemetry"); t && t->find("doorbell_rings") &&
                                                 t->find("doorbell_rings")->as_number() > 0) {
    // The publisher is usually awake when the samples come, and the ring is an atomic add
    // and a load; the system call that wakes a sleeping publisher is what it can cost.
    const double rings = t->find("doorbell_rings")->as_number();
    const double wakes = t->find("doorbell_wakes")->as_number();
    const double wake_ns = t->find("doorbell_wake_ns")->as_number();
    std::fprintf(out, "  telemetry doorbell: the RT thread woke the publisher with a system call in %.0f of %.0f cycles "
                 "(%.2f %%), %.0f ns each, %.1f ns a cycle on average\n",
                 wakes, rings, 100.0 * wakes / rings, wakes > 0 ? wake_ns / wakes : 0.0, wake_ns / rings);
  }
  if (const auto* t = summary.find("telemetry"); t && t->find("commands_malformed") &&
                                                 t->find("commands_malformed")->as_number() > 0)
    say(stdout, Severity::warning, "  WARNING: %llu malformed command samples dropped (not a lode::msg::Command)\n",
        static_cast<unsigned long long>(t->find("commands_malformed")->as_number()));
  if (const auto* h = summary.find("hot_swap"); h && h->find("swaps")->as_number() > 0)
    std::fprintf(out, "  hot swap: %llu swaps, RT cost per exchange p50 %.0f ns, max %.0f ns; overruns in a swap cycle "
                 "(or the next) %llu\n",
                 static_cast<unsigned long long>(h->find("swaps")->as_number()),
                 h->find("rt_cost_p50_ns") ? h->find("rt_cost_p50_ns")->as_number() : 0.0,
                 h->find("rt_cost_max_ns") ? h->find("rt_cost_max_ns")->as_number() : 0.0,
                 static_cast<unsigned long long>(h->find("overruns_at_swap_cycles")->as_number()));
  if (f.analysis.dropped() > 0)
    say(stdout, Severity::warning, "  WARNING: %llu recorded samples dropped (consumer too slow)\n",
        static_cast<unsigned long long>(f.analysis.dropped()));
  if (const auto* recs = summary.find("recordings")) {
    for (const auto& r : recs->elements()) {
      const auto* error = r.find("error");
      std::fprintf(out, "  recording: %s: %llu cycles%s%s\n", r.find("file")->as_string().c_str(),
                   static_cast<unsigned long long>(r.find("cycles")->as_number()),
                   error ? (", " + std::to_string(static_cast<unsigned long long>(r.find("lost")->as_number())) +
                            " lost; FAILED: " + error->as_string()).c_str()
                         : "",
                   !error && r.find("dropped")->as_number() > 0 ? ", some dropped (see the summary)" : "");
    }
  }
  // The outcome, and that the outputs are at their safe values: pipeline.deactivate() has
  // driven them before this summary, whatever ended the run.
  const auto cycles = static_cast<unsigned long long>(st.cycles.load());
  if (f.result.faulted)
    say(stdout, Severity::error, "  FAULT: %s (outputs driven safe)\n", f.result.fault.c_str());
  else if (f.result.stopped_by_request)
    say(stdout, Severity::notice, "  stopped by signal at cycle %llu (outputs driven safe)\n", cycles);
  else
    say(stdout, Severity::notice, "  completed %llu cycles (outputs driven safe)\n", cycles);
}

}  // namespace lode::cli
