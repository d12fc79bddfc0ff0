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
#include "journal_output.hpp"
#include "load_config.hpp"
#include "log_drain.hpp"
#include "lode/crash_guard.hpp"
#include "lode/dds/participant.hpp"
#include "run_analysis.hpp"
#include "run_report.hpp"
#include "run_services.hpp"
#include "service_notify.hpp"

namespace lode::cli {
namespace {

using SteadyClock = std::chrono::steady_clock;

void declare(Declare& d) {
  d.positional("CONFIG", "the pipeline file", 1, 1);
  d.number("--duration", "S", "how long to run (default: the pipeline's duration_s, else 10 s)", 0, 1e9);
  d.flag("--until-stopped", "run until SIGTERM or Ctrl-C, whatever duration_s says (a service: systemctl stop)");
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
      say(stderr, Severity::error, "lode: LODE_DDS_DOMAIN must be an integer in [0, 232], got '%s'\n", std::getenv("LODE_DDS_DOMAIN"));
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
/// otherwise; none under the journal (the service's STATUS= says it to `systemctl status`
/// without a line a second in the log).
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
  /// Clears the line in place on a terminal, so that a message printed next is not mixed into it.
  void clear() const {
    if (!quiet_ && tty_) std::fprintf(stderr, "\r%-150s\r", "");
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
  const bool until_stopped = args.has_flag("--until-stopped");
  if (until_stopped && args.has("--duration")) {
    say(stderr, Severity::error, "lode: --duration and --until-stopped contradict each other; give one\n");
    return kExitConfig;
  }
  const double duration = args.number("--duration", p.default_duration_s().value_or(10.0));
  // 0 cycles: the scheduler runs until stopped.
  const auto cycles =
      until_stopped ? std::uint64_t{0} : static_cast<std::uint64_t>(std::llround(duration * p.rate_hz()));
  if (cycles == 0 && !until_stopped) {
    // The scheduler reads 0 cycles as "until stopped": never let a short duration round to it.
    say(stderr, Severity::error, "lode: a duration of %g s is shorter than one cycle at %g Hz\n", duration, p.rate_hz());
    return kExitConfig;
  }
  const auto options = service_options(args, simulated);
  if (!options) return kExitConfig;
  // Under systemd: lines carry their priority, and no status line (nobody watches a journal
  // redraw); the service manager is told when the loop runs and that it keeps running.
  const bool journal = is_journal_stream(STDERR_FILENO);
  ServiceNotifier notifier;
  if (!simulated) {
    // Before any other thread exists: they all inherit the affinity.
    if (const auto w = keep_threads_off_cpu(p.realtime().cpu); !w.empty())
      say(stderr, Severity::warning, "lode: warning: %s\n", w.c_str());
  }

  // The end-of-run summary, computed as the rows are drained (memory independent of length).
  RunAnalysis analysis(p);
  analysis.print_to(severity_stream(stdout, Severity::info));
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
    say(stderr, Severity::error, "lode: %s; nothing was started\n", services.error().c_str());
    return kExitFault;
  }
  if (!(*services)->wait_for_subscribers()) {
    say(stderr, Severity::error, "lode: fewer than %d subscribers matched within %g s; nothing was started\n",
        options->wait_subscribers, options->wait_s);
    return kExitFault;
  }

  StatusLine status(p, sched, analysis, !simulated, args.has_flag("--quiet") || journal);
  // Events as they happen, under the journal (a terminal has the status line and the
  // summary); counted for the service's STATUS either way.
  const bool echo_events = journal;
  std::size_t event_cursor = 0;
  std::uint64_t faults_seen = 0;
  const auto follow_events = [&] {
    for (const Event& e : events.since(event_cursor)) {
      const bool fault = e.kind == "fault" || e.kind == "error";
      if (fault || e.kind == "health") ++faults_seen;
      // On a terminal too, at once: another pipeline of this name on the domain (its commands
      // are refused meanwhile). Everything else a terminal has in the status line, the RT
      // log's own lines or the summary.
      const bool namesake = e.kind == "namesake";
      if (!(echo_events || namesake) || e.kind == "start" || e.kind == "stop") continue;  // the start line and the summary say those
      const Severity severity = fault ? Severity::error
                                : e.kind == "warning" || e.kind == "health" || e.kind == "dropped" || namesake
                                    ? Severity::warning
                                    : Severity::info;
      if (!echo_events) status.clear();
      say(stderr, severity, "lode: %s: %s\n", e.kind.c_str(), e.text.c_str());
    }
  };
  std::uint64_t status_executed = 0;
  auto status_at = SteadyClock::now();
  const auto service_status = [&] {
    const auto& st = sched.stats();
    const auto now = SteadyClock::now();
    const std::uint64_t executed = st.executed.load();
    const double dt = std::chrono::duration<double>(now - status_at).count();
    const double rate = dt > 0 ? static_cast<double>(executed - status_executed) / dt : 0.0;
    const bool stalled = executed == status_executed && executed > 0;  // `systemctl status` shows it first
    status_executed = executed;
    status_at = now;
    char text[160];
    std::snprintf(text, sizeof text, "%scycle %llu, %.1f Hz, overruns %llu, faults %llu",
                  stalled ? "NO PROGRESS: " : "", static_cast<unsigned long long>(st.cycles.load()), rate,
                  static_cast<unsigned long long>(st.overruns.load()), static_cast<unsigned long long>(faults_seen));
    return std::string(text);
  };
  const auto safe_outcome = [&](const RunResult& r) {
    const auto cycle = std::to_string(sched.stats().cycles.load());
    return (r.faulted ? "fault: " + r.fault : r.stopped_by_request ? "stopped by signal at cycle " + cycle
                                                                   : "completed " + cycle + " cycles") +
           " (outputs driven safe)";
  };
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
    follow_events();
    if (stop_requested().load())
      notifier.stopping("stopping on a signal at cycle " + std::to_string(sched.stats().cycles.load()) +
                        ": driving the outputs safe");
    // The RT loop's progress, seen from here: a stuck step() stops the count, not this thread.
    if (notifier.on_idle(sched.stats().executed.load(), service_status) == ServiceNotifier::Idle::stalled)
      say(stderr, Severity::error,
          "lode: the real-time loop has made no progress for %.1f s (stuck at cycle %llu); watchdog pings withheld\n",
          std::chrono::duration<double>(notifier.watchdog_interval()).count() / 2,
          static_cast<unsigned long long>(sched.stats().cycles.load()));
  };
  // A bug that kills the process (SIGSEGV, an exception out of step()) still drives the outputs safe.
  CrashGuard crash_guard(p);
  char rate_and_length[96];
  if (until_stopped)
    std::snprintf(rate_and_length, sizeof rate_and_length, "%g Hz, %s clock, until stopped", p.rate_hz(), clock_name.c_str());
  else
    std::snprintf(rate_and_length, sizeof rate_and_length, "%g Hz, %s clock, %g s", p.rate_hz(), clock_name.c_str(), duration);
  const std::string start_text = "pipeline '" + p.name() + "' at " + rate_and_length;
  const auto outcome = execute_run(
      p, sched, events, **services, cycles, start_text, on_idle,
      [&] {
        analysis.drain();
        status.print(true);
        drain.stop();
        follow_events();
        notifier.stopping("stopping at cycle " + std::to_string(sched.stats().cycles.load()) +
                          ": outputs driven safe");
      },
      [&] {
        // On a terminal the status line shows the start; a service's log needs a line.
        if (!journal && !notifier.active()) return;
        char length[48] = "until stopped";
        if (!until_stopped) std::snprintf(length, sizeof length, "%g s", duration);
        say(stderr, Severity::info, "lode: started pipeline '%s' (%s) at %g Hz, %s clock, %s\n", p.name().c_str(),
            loaded->path.c_str(), p.rate_hz(), clock_name.c_str(), length);
      });
  if (!outcome) {
    say(stderr, Severity::error, "lode: %s\n", outcome.error().c_str());
    notifier.status("not started: " + outcome.error());
    return kExitFault;
  }
  const RunResult& result = *outcome;
  follow_events();  // the stop event and what services.finish() posted
  // Under the journal each of these was already echoed as its "warning" event.
  if (!echo_events)
    for (const auto& w : result.warnings) say(stderr, Severity::warning, "lode: warning: %s\n", w.c_str());

  const RunFacts facts{p, sched, result, analysis, **services, events, loaded->path, simulated};
  const Json summary = finish_run_summary(facts);
  print_run_summary(summary, facts);
  if (args.has("--summary-json")) {
    if (Status written = write_text_file(args.option("--summary-json"), summary.dump() + "\n"); !written) {
      say(stderr, Severity::error, "lode: %s\n", written.message().c_str());
      return kExitFault;
    }
  }
  notifier.status(safe_outcome(result));
  const int rc = result.faulted ? kExitFault : kExitOk;
  if ((*services)->dds_stuck()) {
    // Results are written; Fast DDS's own teardown would block on the stuck thread.
    say(stderr, Severity::warning, "lode: warning: telemetry publisher stuck inside Fast DDS; leaving without DDS teardown\n");
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
