// lode: run, check and inspect lodestone pipelines.
//
// Exit codes: 0 success, 1 runtime fault, 2 invalid configuration (or usage).
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "analysis.hpp"
#include "run_analysis.hpp"
#include "cli.hpp"
#include "command_line.hpp"
#include "run_services.hpp"
#include "lode/crash_guard.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/realtime.hpp"
#include "lode/rt_log.hpp"
#include "lode/scheduler.hpp"
#include "log_drain.hpp"
#include "replay.hpp"

namespace {

using lode::cli::Args;
using lode::cli::kExitConfig;
using lode::cli::kExitFault;
using lode::cli::kExitOk;


/// The pipeline named by the command's one positional argument, with the registry whose
/// libraries its blocks live in (declared first: destroyed last).
struct LoadedConfig {
  std::unique_ptr<lode::PluginRegistry> registry;
  std::unique_ptr<lode::Pipeline> pipeline;
  std::string path;
};

/// Prints every diagnostic and returns nullopt when there is nothing to run. (The command
/// line has checked that there is exactly one CONFIG.)
std::optional<LoadedConfig> load_config_argument(const Args& args) {
  if (args.positional.size() != 1) return std::nullopt;
  LoadedConfig loaded;
  loaded.path = args.positional[0];
  loaded.registry = std::make_unique<lode::PluginRegistry>();
  lode::Diagnostics diag;
  loaded.pipeline = lode::Pipeline::load_file(loaded.path, *loaded.registry, diag);
  if (!loaded.pipeline) {
    std::fputs(diag.format().c_str(), stderr);
    std::fprintf(stderr, "lode: %zu problem%s in %s; nothing was started\n", diag.size(),
                 diag.size() == 1 ? "" : "s", loaded.path.c_str());
    return std::nullopt;
  }
  return loaded;
}

// ---------------------------------------------------------------------------------------
int cmd_plugins(const Args& args) {
  lode::PluginRegistry reg;
  auto listing = reg.discover_all();
  if (!args.positional.empty()) {  // `lode plugins NAME`: that plugin only
    const std::string& wanted = args.positional.front();
    std::erase_if(listing.plugins, [&](const auto& p) { return wanted != p.descriptor->name; });
    if (listing.plugins.empty()) {
      std::fprintf(stderr, "lode: no plugin named '%s' (`lode plugins` lists them)\n", wanted.c_str());
      return kExitConfig;
    }
  }
  lode::Json out = lode::Json::array();
  for (const auto& p : listing.plugins) {
    const auto* d = p.descriptor;
    lode::Json j = lode::Json::object();
    j["name"] = d->name;
    j["kind"] = lode::to_string(d->kind);
    j["version"] = d->version;
    j["summary"] = d->summary;
    j["file"] = p.path;
    lode::Json params = lode::Json::array();
    for (std::size_t i = 0; i < d->param_count; ++i) {
      lode::Json pj = lode::Json::object();
      pj["name"] = d->params[i].name;
      pj["type"] = d->params[i].type;
      pj["default"] = d->params[i].default_value ? lode::Json(d->params[i].default_value) : lode::Json();
      pj["description"] = d->params[i].description;
      params.push(std::move(pj));
    }
    j["parameters"] = std::move(params);
    lode::Json ports = lode::Json::array();
    for (std::size_t i = 0; i < d->port_count; ++i) {
      lode::Json pj = lode::Json::object();
      pj["name"] = d->ports[i].name;
      pj["direction"] = d->ports[i].direction;
      pj["description"] = d->ports[i].description;
      ports.push(std::move(pj));
    }
    j["ports"] = std::move(ports);
    out.push(std::move(j));
  }
  if (args.has_flag("--json")) {
    std::cout << out.dump() << "\n";
  } else {
    for (const auto& p : listing.plugins) {
      const auto* d = p.descriptor;
      std::printf("%-26s %-7s %-8s %s\n", d->name, lode::to_string(d->kind), d->version, d->summary);
      for (std::size_t i = 0; i < d->port_count; ++i)
        std::printf("    %-4s %-18s %s\n", d->ports[i].direction, d->ports[i].name, d->ports[i].description);
      for (std::size_t i = 0; i < d->param_count; ++i) {
        const auto& pd = d->params[i];
        std::printf("    %-23s %-13s %-12s %s\n", pd.name, pd.type,
                    pd.default_value ? pd.default_value : "(required)", pd.description);
      }
    }
    std::printf("%zu plugins\n", listing.plugins.size());
  }
  for (const auto& e : listing.errors) std::fprintf(stderr, "lode: %s\n", e.c_str());
  return listing.errors.empty() ? kExitOk : kExitFault;
}

int cmd_check(const Args& args) {
  auto loaded = load_config_argument(args);
  if (!loaded) return kExitConfig;
  const auto& p = loaded->pipeline;
  std::printf("%s: ok: pipeline '%s' at %g Hz, %zu operations per cycle:", args.positional[0].c_str(),
              p->name().c_str(), p->rate_hz(), p->ops().size());
  for (const auto& op : p->ops()) std::printf(" %s", op.label.c_str());
  std::printf("\n");
  return kExitOk;
}

int cmd_describe(const Args& args) {
  auto loaded = load_config_argument(args);
  if (!loaded) return kExitConfig;
  std::cout << loaded->pipeline->describe().dump() << "\n";
  return kExitOk;
}

int cmd_rtcheck(const Args&) {
  const auto r = lode::realtime_host_report();
  std::cout << r.dump() << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------------------------------
// run

std::string format_value(double v, const std::string& unit) {
  auto [scale, shown] = lode::analysis::display_scale(unit, v);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%+.3f %s", v * scale, shown.c_str());
  return buf;
}

lode::Json timing_json(const lode::Pipeline& p, const lode::Scheduler& s, const lode::RunResult& r,
                       bool simulated, double sim_seconds) {
  lode::Json j = lode::Json::object();
  const auto& st = s.stats();
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
  lode::Json blocks = lode::Json::object();
  for (const auto& op : p.ops()) blocks[op.label] = op.exec_time->summary_us();
  j["block_exec_time"] = std::move(blocks);
  return j;
}

int cmd_run(const Args& args) {
  // Without --clock, the pipeline's realtime.clock (sim unless it drives hardware).
  std::string clock_name = args.options.count("--clock") ? args.options.at("--clock") : "";
  if (!clock_name.empty() && clock_name != "sim" && clock_name != "real") {
    std::fprintf(stderr, "lode: --clock must be sim or real, got '%s'\n", clock_name.c_str());
    return kExitConfig;
  }
  const bool quiet = args.has_flag("--quiet");
  auto loaded = load_config_argument(args);
  if (!loaded) return kExitConfig;
  auto& p = loaded->pipeline;
  const std::string& config = loaded->path;
  if (clock_name.empty()) clock_name = p->realtime().real_clock ? "real" : "sim";
  double duration = p->default_duration_s().value_or(10.0);
  if (args.options.count("--duration")) {
    char* end = nullptr;
    duration = std::strtod(args.options.at("--duration").c_str(), &end);
    if (!end || *end || !(duration > 0)) {
      std::fprintf(stderr, "lode: --duration must be a positive number of seconds\n");
      return kExitConfig;
    }
  }
  const auto cycles = static_cast<std::uint64_t>(std::llround(duration * p->rate_hz()));
  if (cycles == 0) {
    // The scheduler reads 0 cycles as "until stopped": never let a short duration round to it.
    std::fprintf(stderr, "lode: a duration of %g s is shorter than one cycle at %g Hz\n", duration,
                 p->rate_hz());
    return kExitConfig;
  }

  // The end-of-run summary, computed as the rows are drained (memory independent of length).
  lode::cli::RunAnalysis analysis(*p);

  lode::EventLog events;
  lode::LogDrain drain(events);
  lode::cli::install_stop_handlers();

  std::unique_ptr<lode::Clock> clock;
  if (clock_name == "sim") clock = std::make_unique<lode::SimulatedClock>();
  else clock = std::make_unique<lode::RealClock>(p->realtime().spin_us * 1000);
  lode::Scheduler sched(*p, *clock, events);
  sched.add_tap(&analysis.tap());

  lode::cli::RunServiceOptions service_options;
  service_options.telemetry = !args.has_flag("--no-telemetry");
  service_options.simulated = clock_name == "sim";
  service_options.local_control = !args.has_flag("--no-local-control");
  service_options.record_path = args.option("--record");
  // --domain, else LODE_DDS_DOMAIN, else the YAML's telemetry.domain: the environment that
  // points `lode echo` at a domain points the pipeline's publisher at the same one.
  if (args.has("--domain")) {
    const auto d = lode::cli::number_option(args, "--domain", 0, 0, 232);
    if (!d) return kExitConfig;
    service_options.domain = static_cast<int>(*d);
  } else if (const char* env = std::getenv("LODE_DDS_DOMAIN"); env != nullptr && *env != '\0') {
    char* end = nullptr;
    const long d = std::strtol(env, &end, 10);
    if (*end != '\0' || d < 0 || d > 232) {
      std::fprintf(stderr, "lode: LODE_DDS_DOMAIN must be an integer in [0, 232], got '%s'\n", env);
      return kExitConfig;
    }
    service_options.domain = static_cast<int>(d);
  }
  if (args.has("--wait-subscribers")) {
    const auto n = lode::cli::number_option(args, "--wait-subscribers", 0, 0, 1000);
    const auto w = lode::cli::number_option(args, "--wait", 10, 0, 3600);
    if (!n || !w) return kExitConfig;
    service_options.wait_subscribers = static_cast<int>(*n);
    service_options.wait_s = *w;
  }
  // Everything that can fail starts before activation: nothing runs half-configured.
  auto services = lode::cli::RunServices::start(*p, sched, events, service_options);
  if (!services) {
    std::fprintf(stderr, "lode: %s; nothing was started\n", services.error().c_str());
    return kExitFault;
  }
  if (!(*services)->wait_for_subscribers()) {
    std::fprintf(stderr, "lode: fewer than %d subscribers matched within %g s; nothing was started\n",
                 service_options.wait_subscribers, service_options.wait_s);
    return kExitFault;
  }

  const bool tty = isatty(STDERR_FILENO) != 0;
  auto last_print = std::chrono::steady_clock::now();
  auto status_line = [&](bool final_line) {
    const auto& st = sched.stats();
    const double t = static_cast<double>(st.last_time_ns.load()) * 1e-9;
    std::string line = "cycle " + std::to_string(st.cycles.load());
    char buf[160];
    if (clock_name == "real") {
      std::snprintf(buf, sizeof buf, "  t %.2f s  %.1f Hz  wake max %.0f us  overruns %llu", t,
                    t > 0 ? static_cast<double>(st.executed.load()) / (t + 1.0 / p->rate_hz()) : 0.0,
                    static_cast<double>(st.wake_latency.max()) / 1e3,
                    static_cast<unsigned long long>(st.overruns.load()));
    } else {
      std::snprintf(buf, sizeof buf, "  t %.2f s (simulated)  overruns 0", t);
    }
    line += buf;
    if (const lode::SignalRef* sig = analysis.shown(); sig != nullptr) {
      const std::vector<double> last = analysis.last_shown();
      if (!last.empty()) {
        line += "  " + sig->name() + ":";
        for (std::size_t i = 0; i < sig->size(); ++i)
          line += " " + (*sig->elements)[i].name + " " + format_value(last[i], (*sig->elements)[i].unit);
      }
    }
    if (quiet) return;
    if (tty) std::fprintf(stderr, "\r%-150s%s", line.c_str(), final_line ? "\n" : "");
    else std::fprintf(stderr, "%s\n", line.c_str());
  };
  // --speed X (simulated clock): simulated time runs at most X times real time, so a
  // simulation can be watched live; the outputs are those of an unpaced run.
  const auto speed = lode::cli::number_option(args, "--speed", 0, 0, 1e9);
  if (!speed) return kExitConfig;
  const auto paced_start = std::chrono::steady_clock::now();
  auto on_idle = [&] {
    (*services)->on_idle();
    if (*speed > 0 && clock_name == "sim") {
      const double sim_s = static_cast<double>(sched.stats().last_time_ns.load()) * 1e-9;
      std::this_thread::sleep_until(paced_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                      std::chrono::duration<double>(sim_s / *speed)));
    }
    analysis.drain();
    const auto now = std::chrono::steady_clock::now();
    if (now - last_print > std::chrono::milliseconds(tty ? 200 : 1000)) {
      last_print = now;
      status_line(false);
    }
  };
  // A bug that kills the process (SIGSEGV, an exception out of step()) still drives the outputs safe.
  lode::CrashGuard crash_guard(*p);
  const auto outcome = lode::cli::execute_run(
      *p, sched, events, **services, cycles,
      "pipeline '" + p->name() + "' at " + std::to_string(p->rate_hz()) + " Hz, " + clock_name + " clock, " +
          std::to_string(duration) + " s",
      on_idle, [&] {
        analysis.drain();
        status_line(true);
        drain.stop();
      });
  if (!outcome) {
    std::fprintf(stderr, "lode: %s\n", outcome.error().c_str());
    return kExitFault;
  }
  const auto& result = *outcome;
  const auto& st = sched.stats();
  const double sim_seconds = static_cast<double>(st.cycles.load()) / p->rate_hz();
  for (const auto& w : result.warnings) std::fprintf(stderr, "lode: warning: %s\n", w.c_str());

  lode::Json summary = lode::Json::object();
  summary["pipeline"] = p->name();
  summary["config"] = config;
  summary["result"] = result.faulted ? "fault" : result.stopped_by_request ? "stopped" : "completed";
  if (result.faulted) summary["fault"] = result.fault;
  const lode::Json figures = analysis.finish();
  for (const auto& [k, v] : figures.members()) summary[k] = v;
  summary["timing"] = timing_json(*p, sched, result, clock_name == "sim", sim_seconds);
  summary["recording"] = lode::Json::object();
  summary["recording"]["samples"] = analysis.samples();
  summary["recording"]["dropped"] = analysis.dropped();
  summary["rt_log_dropped"] = lode::rt_log_ring().dropped();
  const lode::Json service_summary = (*services)->summary();
  for (const auto& [k, v] : service_summary.members()) summary[k] = v;
  summary["warnings"] = lode::Json::array();
  for (const auto& w : result.warnings) summary["warnings"].push(w);
  summary["events"] = events.to_json();
  // The summary keeps the first and the latest events; how many fell between is said, not hidden.
  summary["events_posted"] = events.posted();
  summary["events_dropped"] = events.dropped();
  summary["events_suppressed"] = events.suppressed();  // refused commands beyond 10 a second

  // Timing, human-readable.
  const auto& tj = *summary.find("timing");
  if (clock_name == "real") {
    const auto& wl = *tj.find("wake_latency");
    std::printf("  timing: %llu cycles run at %.1f Hz achieved; wake-up latency p50 %.1f us, p99 %.1f us, "
                "p99.9 %.1f us, max %.1f us; overruns %llu, missed periods %llu\n",
                static_cast<unsigned long long>(st.executed.load()), tj.find("achieved_rate_hz")->as_number(),
                wl.find("p50_us")->as_number(), wl.find("p99_us")->as_number(),
                wl.find("p999_us")->as_number(), wl.find("max_us")->as_number(),
                static_cast<unsigned long long>(st.overruns.load()),
                static_cast<unsigned long long>(st.missed_periods.load()));
  } else {
    std::printf("  timing: %llu cycles simulated in %.3f s wall (%.0fx real time)\n",
                static_cast<unsigned long long>(st.cycles.load()), result.wall_s,
                tj.find("speed_vs_realtime")->as_number());
  }
  std::printf("  step cost per block (p50 / p99 / max, us):");
  for (const auto& op : p->ops())
    std::printf("  %s %.2f/%.2f/%.1f", op.label.c_str(), static_cast<double>(op.exec_time->percentile(0.5)) / 1e3,
                static_cast<double>(op.exec_time->percentile(0.99)) / 1e3,
                static_cast<double>(op.exec_time->max()) / 1e3);
  std::printf("\n");
  if (const auto* t = summary.find("telemetry"))
    std::printf("  telemetry: domain %lld, %llu samples handed over, %llu dropped by the RT side (rings full), "
                "%llu published\n",
                static_cast<long long>(t->find("domain")->as_number()),
                static_cast<unsigned long long>(t->find("samples_offered")->as_number()),
                static_cast<unsigned long long>(t->find("ring_dropped")->as_number()),
                static_cast<unsigned long long>(t->find("published") ? t->find("published")->as_number() : 0));
  if (const auto* h = summary.find("hot_swap"); h && h->find("swaps")->as_number() > 0)
    std::printf("  hot swap: %llu swaps, RT cost per exchange p50 %.0f ns, max %.0f ns; overruns in a swap cycle "
                "(or the next) %llu\n",
                static_cast<unsigned long long>(h->find("swaps")->as_number()),
                h->find("rt_cost_p50_ns") ? h->find("rt_cost_p50_ns")->as_number() : 0.0,
                h->find("rt_cost_max_ns") ? h->find("rt_cost_max_ns")->as_number() : 0.0,
                static_cast<unsigned long long>(h->find("overruns_at_swap_cycles")->as_number()));
  if (analysis.dropped() > 0)
    std::printf("  WARNING: %llu recorded samples dropped (consumer too slow)\n",
                static_cast<unsigned long long>(analysis.dropped()));
  if (const auto* recs = summary.find("recordings")) {
    for (const auto& r : recs->elements()) {
      const auto* error = r.find("error");
      std::printf("  recording: %s: %llu cycles%s%s\n", r.find("file")->as_string().c_str(),
                  static_cast<unsigned long long>(r.find("cycles")->as_number()),
                  error ? (", " + std::to_string(static_cast<unsigned long long>(r.find("lost")->as_number())) +
                           " lost; FAILED: " + error->as_string()).c_str()
                        : "",
                  !error && r.find("dropped")->as_number() > 0 ? ", some dropped (see the summary)" : "");
    }
  }
  if (result.faulted) std::printf("  FAULT: %s (outputs driven safe)\n", result.fault.c_str());

  if (args.options.count("--summary-json")) {
    const auto& path = args.options.at("--summary-json");
    std::ofstream f(path);
    if (!f) {
      std::fprintf(stderr, "lode: cannot write %s\n", path.c_str());
      return kExitFault;
    }
    f << summary.dump() << "\n";
  }
  const int rc = result.faulted ? kExitFault : kExitOk;
  if ((*services)->dds_stuck()) {
    // Results are written; Fast DDS's own teardown would block on the stuck thread.
    std::fprintf(stderr, "lode: warning: telemetry publisher stuck inside Fast DDS; leaving without DDS teardown\n");
    std::fflush(nullptr);
    _exit(rc);
  }
  return rc;
}

// ---------------------------------------------------------------------------------------
int cmd_bench(const Args& args) {
  auto loaded = load_config_argument(args);
  if (!loaded) return kExitConfig;
  auto& p = loaded->pipeline;
  std::uint64_t cycles = 100000;
  if (args.options.count("--cycles")) cycles = std::strtoull(args.options.at("--cycles").c_str(), nullptr, 10);
  if (auto st = p->activate(); !st) {
    std::fprintf(stderr, "lode: %s\n", st.message().c_str());
    return kExitFault;
  }
  lode::Histogram whole;
  lode::Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  lode::RealClock clock;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    const auto t0 = clock.now_ns();
    const auto r = p->run_cycle(tick, true);
    whole.record(clock.now_ns() - t0);
    if (r.status != lode::StepStatus::ok) {
      std::fprintf(stderr, "lode: fault at cycle %llu in %s\n", static_cast<unsigned long long>(k),
                   p->ops()[static_cast<std::size_t>(r.failed_op)].label.c_str());
      return kExitFault;
    }
  }
  p->deactivate();
  std::printf("%-22s %10s %10s %10s %10s\n", "operation", "p50 ns", "p99 ns", "mean ns", "max ns");
  for (const auto& op : p->ops())
    std::printf("%-22s %10lld %10lld %10.0f %10lld\n", op.label.c_str(),
                static_cast<long long>(op.exec_time->percentile(0.5)),
                static_cast<long long>(op.exec_time->percentile(0.99)), op.exec_time->mean(),
                static_cast<long long>(op.exec_time->max()));
  std::printf("%-22s %10lld %10lld %10.0f %10lld   (%llu cycles, includes timing overhead)\n",
              "whole cycle", static_cast<long long>(whole.percentile(0.5)),
              static_cast<long long>(whole.percentile(0.99)), whole.mean(),
              static_cast<long long>(whole.max()), static_cast<unsigned long long>(cycles));
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  const std::vector<lode::cli::CommandEntry> commands = {
      {"run", cmd_run},          {"check", cmd_check},
      {"describe", cmd_describe}, {"plugins", cmd_plugins},
      {"replay", lode::cli::cmd_replay}, {"bench", cmd_bench},
      {"rtcheck", cmd_rtcheck},  {"topics", lode::cli::cmd_topics},
      {"echo", lode::cli::cmd_echo}, {"record", lode::cli::cmd_record},
      {"set", lode::cli::cmd_set},  {"swap", lode::cli::cmd_swap}};
  try {
    return lode::cli::run_command_line(argc, argv, commands);
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "lode: internal error: %s\n", ex.what());
    return kExitFault;
  }
}
