// lode rtcheck [CONFIG] [--json] [--latency DURATION]: whether this host is fit to run a
// pipeline's real-time loop (PASS / WARN / FAIL per check, with the exact fix), and optionally
// how late a periodic SCHED_FIFO thread wakes up on it. Exit 0 fit, 1 not fit, 2 bad input.
#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "host_checks.hpp"
#include "load_config.hpp"
#include "rtcheck_latency.hpp"

namespace lode::cli {

namespace {

Json target_json(const HostTarget& t) {
  Json j = Json::object();
  j["pipeline"] = t.from_pipeline() ? Json(t.pipeline) : Json(nullptr);
  j["config"] = t.from_pipeline() ? Json(t.config_path) : Json(nullptr);
  j["priority"] = t.priority;
  j["cpu"] = t.cpu;
  j["lock_memory"] = t.lock_memory;
  j["period_us"] = static_cast<double>(t.period_ns) / 1000.0;
  return j;
}

std::string target_text(const HostTarget& t) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s: SCHED_FIFO priority %d, %s, memory %s, period %.1f us\n",
                t.from_pipeline() ? ("pipeline '" + t.pipeline + "' (" + t.config_path + ")").c_str()
                                  : "this host in general (no pipeline)",
                t.priority, t.cpu >= 0 ? ("CPU " + std::to_string(t.cpu)).c_str() : "no particular CPU",
                t.lock_memory ? "locked" : "not locked", static_cast<double>(t.period_ns) / 1000.0);
  return buf;
}

int rtcheck(const Args& args) {
  std::optional<std::int64_t> duration_ns;
  if (args.has("--latency")) {
    std::string why;
    duration_ns = parse_duration_ns(args.option("--latency"), why);
    if (!duration_ns) {
      std::fprintf(stderr, "lode: --latency: %s\n", why.c_str());
      return kExitConfig;
    }
  }
  HostTarget target;  // without CONFIG: the defaults, "this host in general"
  std::optional<LoadedConfig> loaded;
  if (!args.positional.empty()) {
    loaded = load_config(args.positional[0]);
    if (!loaded) return kExitConfig;
    const auto& p = *loaded->pipeline;
    target.pipeline = p.name();
    target.config_path = loaded->path;
    target.priority = p.realtime().priority;
    target.cpu = p.realtime().cpu;
    target.lock_memory = p.realtime().lock_memory;
    target.period_ns = p.period_ns();
  }
  auto checks = run_host_checks(HostFiles("/"), target);

  std::optional<LatencyReport> latency;
  if (duration_ns) {
    install_stop_handlers();  // Ctrl-C ends the measurement early; what was measured is reported
    LatencyPlan plan;
    plan.cpu = target.cpu;
    plan.priority = target.priority;
    plan.period_ns = target.period_ns;
    plan.duration_ns = *duration_ns;
    // Timing the cycle runs it as `lode bench` does, activating its io blocks: a pipeline on
    // the real clock drives hardware (a stage that may be live, a board lode@ holds), so its
    // cycle is not run here.
    if (loaded && loaded->pipeline->realtime().real_clock)
      plan.cycle_cost_skipped = "it drives hardware (realtime.clock: real); running its cycle would drive the hardware";
    else if (loaded)
      plan.pipeline = loaded->pipeline.get();
    if (!args.has_flag("--json"))
      std::fprintf(stderr, "lode rtcheck: measuring wake-up latency for %.1f s...\n", static_cast<double>(*duration_ns) / 1e9);
    latency = measure_latency(plan);
    for (auto& c : latency_checks(*latency)) checks.push_back(std::move(c));
  }
  const bool fit = host_fit(checks);

  if (args.has_flag("--json")) {
    Json j = Json::object();
    j["target"] = target_json(target);
    j["checks"] = checks_json(checks);
    if (latency) j["latency"] = latency_json(*latency);
    j["fit"] = fit;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << target_text(target) << checks_text(checks);
    if (latency) std::cout << "\n" << latency_text(*latency);
    std::size_t fails = 0, warns = 0;
    for (const auto& c : checks) {
      fails += c.status == CheckStatus::fail;
      warns += c.status == CheckStatus::warn;
    }
    std::cout << "\n" << (fit ? "fit" : "NOT fit") << " for real-time runs: " << fails << " FAIL, " << warns
              << " WARN (docs/rtcheck.md explains each check)\n";
  }
  return fit ? kExitOk : kExitFault;
}

}  // namespace

Command rtcheck_command() {
  return {"rtcheck", "is this host fit for a pipeline's real-time loop: each check with its fix; measures latency",
          [](Declare& d) {
            d.positional("CONFIG", "the pipeline to check the host for (default: the host in general)", 0, 1);
            d.flag("--json", "print the checks (and latency) as JSON");
            d.text("--latency", "DURATION",
                   "also measure wake-up latency on the pipeline's CPU and priority for DURATION (10s, 500ms, 2m, 8h)");
          },
          rtcheck};
}

}  // namespace lode::cli
