// lode run CONFIG: the pipeline on the simulated or the real clock, with a live status line,
// the services around the cycle (local commands, telemetry, recording) and a summary at the
// end. Exit 0 when the run completed or was stopped, 1 on a fault (outputs driven safe), 2
// when the configuration or the command line is invalid (nothing was started).
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "analysis.hpp"
#include "commands.hpp"
#include "load_config.hpp"
#include "log_drain.hpp"
#include "lode/crash_guard.hpp"
#include "lode/dds/participant.hpp"
#include "run_analysis.hpp"
#include "run_report.hpp"
#include "run_services.hpp"

namespace lode::cli {
namespace {

using SteadyClock = std::chrono::steady_clock;

void declare(Declare& d) {
  d.positional("CONFIG", "the pipeline file", 1, 1);
  d.number("--duration", "S", "how long to run (default: the pipeline's duration_s, else until Ctrl-C)", 0, 1e9);
  d.choice("--clock", {"sim", "real"}, "the clock (default: the pipeline's realtime.clock, else sim)");
  d.text("--summary-json", "FILE", "write the summary as JSON");
  d.flag("--quiet", "no status line");
  d.text("--record", "FILE.h5", "record every output at full rate (HDF5)");
  d.integer("--domain", "N", "DDS domain of the telemetry (overrides LODE_DDS_DOMAIN, which overrides telemetry.domain)",
            0, 232);
  d.flag("--no-telemetry", "do not publish over DDS");
  d.integer("--wait-subscribers", "N", "wait for N subscribers before starting", 0, 1000);
  d.number("--wait", "S", "how long --wait-subscribers waits (default 10)", 0, 3600);
  d.number("--speed", "X", "simulated clock: at most X times real time", 1e-6, 1e9);
  d.flag("--no-local-control", "do not serve commands on the local socket");
}

/// What runs around the cycle, from the command line and the environment; nullopt after
/// printing why when LODE_DDS_DOMAIN is not a domain id.
std::optional<RunServiceOptions> service_options(const Args& args, bool simulated) {
  RunServiceOptions o;
  o.telemetry = !args.has_flag("--no-telemetry");
  o.simulated = simulated;
  o.local_control = !args.has_flag("--no-local-control");
  o.record_path = args.option("--record");
  // --domain, else LODE_DDS_DOMAIN, else the YAML's telemetry.domain: the environment that
  // points `lode echo` at a domain points the pipeline's publisher at the same one.
  if (args.has("--domain")) {
    o.domain = static_cast<int>(args.integer("--domain", 0));
  } else if (const auto env = dds::domain_from_environment()) {
    if (*env < 0 || *env > 232) {
      std::fprintf(stderr, "lode: LODE_DDS_DOMAIN must be an integer in [0, 232], got '%s'\n", std::getenv("LODE_DDS_DOMAIN"));
      return std::nullopt;
    }
    o.domain = *env;
  }
  o.wait_subscribers = static_cast<int>(args.integer("--wait-subscribers", 0));
  o.wait_s = args.number("--wait", 10.0);
  return o;
}

std::string format_value(double v, const std::string& unit) {
  auto [scale, shown] = analysis::display_scale(unit, v);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%+.3f %s", v * scale, shown.c_str());
  return buf;
}

/// The one status line while the pipeline runs (cycle, time, rate, worst wake-up latency,
/// overruns, the `monitor.show` signal), rewritten in place on a terminal, one line a second
/// otherwise.
class StatusLine {
 public:
  StatusLine(const Pipeline& p, const Scheduler& s, const RunAnalysis& a, bool real_clock, bool quiet)
      : pipeline_(p), scheduler_(s), analysis_(a), real_clock_(real_clock), quiet_(quiet),
        tty_(isatty(STDERR_FILENO) != 0) {}

  /// Prints when the last line is old enough.
  void maybe_print() {
    const auto now = SteadyClock::now();
    if (now - last_print_ < std::chrono::milliseconds(tty_ ? 200 : 1000)) return;
    last_print_ = now;
    print(false);
  }
  void print(bool final_line) const {
    if (quiet_) return;
    const std::string line = text();
    if (tty_) std::fprintf(stderr, "\r%-150s%s", line.c_str(), final_line ? "\n" : "");
    else std::fprintf(stderr, "%s\n", line.c_str());
  }

 private:
  [[nodiscard]] std::string text() const {
    const auto& st = scheduler_.stats();
    const double t = static_cast<double>(st.last_time_ns.load()) * 1e-9;
    std::string line = "cycle " + std::to_string(st.cycles.load());
    char buf[160];
    if (real_clock_) {
      std::snprintf(buf, sizeof buf, "  t %.2f s  %.1f Hz  wake max %.0f us  overruns %llu", t,
                    t > 0 ? static_cast<double>(st.executed.load()) / (t + 1.0 / pipeline_.rate_hz()) : 0.0,
                    static_cast<double>(st.wake_latency.max()) / 1e3,
                    static_cast<unsigned long long>(st.overruns.load()));
    } else {
      std::snprintf(buf, sizeof buf, "  t %.2f s (simulated)  overruns 0", t);
    }
    line += buf;
    if (const SignalRef* sig = analysis_.shown(); sig != nullptr) {
      const std::vector<double> last = analysis_.last_shown();
      if (!last.empty()) {
        line += "  " + sig->name() + ":";
        for (std::size_t i = 0; i < sig->size(); ++i)
          line += " " + (*sig->elements)[i].name + " " + format_value(last[i], (*sig->elements)[i].unit);
      }
    }
    return line;
  }

  const Pipeline& pipeline_;
  const Scheduler& scheduler_;
  const RunAnalysis& analysis_;
  const bool real_clock_, quiet_, tty_;
  SteadyClock::time_point last_print_ = SteadyClock::now();
};

int run(const Args& args) {
  auto loaded = load_config(args.positional.at(0));
  if (!loaded) return kExitConfig;
  Pipeline& p = *loaded->pipeline;
  // Without --clock, the pipeline's realtime.clock (sim unless it drives hardware).
  const std::string clock_name = args.option("--clock", p.realtime().real_clock ? "real" : "sim");
  const bool simulated = clock_name == "sim";
  const double duration = args.number("--duration", p.default_duration_s().value_or(10.0));
  const auto cycles = static_cast<std::uint64_t>(std::llround(duration * p.rate_hz()));
  if (cycles == 0) {
    // The scheduler reads 0 cycles as "until stopped": never let a short duration round to it.
    std::fprintf(stderr, "lode: a duration of %g s is shorter than one cycle at %g Hz\n", duration, p.rate_hz());
    return kExitConfig;
  }
  const auto options = service_options(args, simulated);
  if (!options) return kExitConfig;

  // The end-of-run summary, computed as the rows are drained (memory independent of length).
  RunAnalysis analysis(p);
  EventLog events;
  LogDrain drain(events);
  install_stop_handlers();
  std::unique_ptr<Clock> clock;
  if (simulated) clock = std::make_unique<SimulatedClock>();
  else clock = std::make_unique<RealClock>(p.realtime().spin_us * 1000);
  Scheduler sched(p, *clock, events);
  sched.add_tap(&analysis.tap());

  // Everything that can fail starts before activation: nothing runs half-configured.
  auto services = RunServices::start(p, sched, events, *options);
  if (!services) {
    std::fprintf(stderr, "lode: %s; nothing was started\n", services.error().c_str());
    return kExitFault;
  }
  if (!(*services)->wait_for_subscribers()) {
    std::fprintf(stderr, "lode: fewer than %d subscribers matched within %g s; nothing was started\n",
                 options->wait_subscribers, options->wait_s);
    return kExitFault;
  }

  StatusLine status(p, sched, analysis, !simulated, args.has_flag("--quiet"));
  // --speed X (simulated clock): simulated time runs at most X times real time, so a
  // simulation can be watched live; the outputs are those of an unpaced run.
  const double speed = args.number("--speed", 0.0);
  const auto paced_start = SteadyClock::now();
  auto on_idle = [&] {
    (*services)->on_idle();
    if (speed > 0 && simulated) {
      const double sim_s = static_cast<double>(sched.stats().last_time_ns.load()) * 1e-9;
      std::this_thread::sleep_until(paced_start + std::chrono::duration_cast<SteadyClock::duration>(
                                                      std::chrono::duration<double>(sim_s / speed)));
    }
    analysis.drain();
    status.maybe_print();
  };
  // A bug that kills the process (SIGSEGV, an exception out of step()) still drives the outputs safe.
  CrashGuard crash_guard(p);
  const auto outcome = execute_run(
      p, sched, events, **services, cycles,
      "pipeline '" + p.name() + "' at " + std::to_string(p.rate_hz()) + " Hz, " + clock_name + " clock, " +
          std::to_string(duration) + " s",
      on_idle, [&] {
        analysis.drain();
        status.print(true);
        drain.stop();
      });
  if (!outcome) {
    std::fprintf(stderr, "lode: %s\n", outcome.error().c_str());
    return kExitFault;
  }
  const RunResult& result = *outcome;
  for (const auto& w : result.warnings) std::fprintf(stderr, "lode: warning: %s\n", w.c_str());

  const RunFacts facts{p, sched, result, analysis, **services, events, loaded->path, simulated};
  const Json summary = finish_run_summary(facts);
  print_run_summary(summary, facts);
  if (args.has("--summary-json")) {
    const std::string path = args.option("--summary-json");
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

}  // namespace

Command run_command() {
  return {"run",
          "run a pipeline: live status line and a summary at the end; publishes the YAML's telemetry: topics over "
          "Fast DDS; serves set/swap/record commands on the local socket $XDG_RUNTIME_DIR/lode/PIPELINE.sock",
          declare, run};
}

}  // namespace lode::cli
