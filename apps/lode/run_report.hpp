// The end of `lode run`: the summary as JSON (what --summary-json writes) and its
// human-readable lines (timing, step cost per block, telemetry, hot swap, recordings, and the
// outcome: fault, stopped or completed, the outputs driven safe in each case).
#pragma once

#include <string>

#include "lode/event_log.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"
#include "run_analysis.hpp"
#include "run_services.hpp"

namespace lode::cli {

/// What a finished run leaves to report.
struct RunFacts {
  const Pipeline& pipeline;
  const Scheduler& scheduler;
  const RunResult& result;
  RunAnalysis& analysis;
  const RunServices& services;
  const EventLog& events;
  const std::string& config;
  bool simulated;
};

/// The summary. Finishing the analysis prints its figures (noise, steps, errors) to stdout.
Json finish_run_summary(const RunFacts& facts);

/// Prints the timing, per-block step cost, telemetry, hot-swap, recording and fault lines.
void print_run_summary(const Json& summary, const RunFacts& facts);

}  // namespace lode::cli
