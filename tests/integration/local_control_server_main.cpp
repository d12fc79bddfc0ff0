// A minimal runner for the local command channel: load a pipeline, put a ControlService and
// a LocalControlServer around it, and cycle until --duration or SIGINT/SIGTERM. No DDS, no
// recorder, no summary: this is `lode run` reduced to what local_control_test.sh checks, so
// the channel is tested before (and independently of) its hookup in `lode run`.
//
//   local_control_server CONFIG [--duration S] [--clock sim|real] [--dir DIR] [--hold]
//
// Prints "ready SOCKET" on stdout once the socket accepts commands and, at the end, one line
// "served: connections N requests N malformed N refused N cycles N". --hold: do not cycle
// (no RT thread; commands are then applied directly by the ControlService).
// Exit codes: 0 done, 1 the server did not start (message on stderr), 2 usage.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "local_control.hpp"
#include "lode/control.hpp"
#include "lode/sdk/diagnostics.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"

namespace {
std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }
}  // namespace

int main(int argc, char** argv) {
  std::string config, clock_name = "real", dir;
  double duration = 0;  // 0: until a signal
  bool hold = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "local_control_server: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--duration") duration = std::atof(value().c_str());
    else if (a == "--clock") clock_name = value();
    else if (a == "--dir") dir = value();
    else if (a == "--hold") hold = true;
    else if (config.empty() && a.rfind("--", 0) != 0) config = a;
    else {
      std::fprintf(stderr, "usage: local_control_server CONFIG [--duration S] [--clock sim|real] [--dir DIR] [--hold]\n");
      return 2;
    }
  }
  if (config.empty() || (clock_name != "sim" && clock_name != "real")) {
    std::fprintf(stderr, "usage: local_control_server CONFIG [--duration S] [--clock sim|real] [--dir DIR] [--hold]\n");
    return 2;
  }
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto pipeline = lode::Pipeline::load_file(config, registry, diag);
  if (!pipeline) {
    std::fputs(diag.format().c_str(), stderr);
    return 2;
  }
  lode::EventLog events;
  lode::ControlService control(*pipeline, events);
  lode::cli::LocalControlOptions options;
  options.dir = dir;
  auto server = lode::cli::LocalControlServer::start(control, pipeline->name(), options);
  if (!server) {
    std::fprintf(stderr, "local_control_server: %s\n", server.error().c_str());
    return 1;
  }
  if ((*server)->replaced_stale()) std::fprintf(stderr, "local_control_server: replaced a stale socket\n");
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  std::unique_ptr<lode::Clock> clock;
  if (clock_name == "sim") clock = std::make_unique<lode::SimulatedClock>();
  else clock = std::make_unique<lode::RealClock>();
  lode::Scheduler scheduler(*pipeline, *clock, events);
  scheduler.add_hook(&control);
  std::printf("ready %s\n", (*server)->path().c_str());
  std::fflush(stdout);

  std::uint64_t cycles = 0;
  if (hold) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(duration > 0 ? duration : 1e9);
    while (!g_stop.load() && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  } else {
    if (auto st = pipeline->activate(); !st) {
      std::fprintf(stderr, "local_control_server: %s\n", st.message().c_str());
      return 1;
    }
    control.set_running(true);
    const auto want = static_cast<std::uint64_t>(duration * pipeline->rate_hz());
    const auto result = scheduler.run(want, g_stop, {});
    control.set_running(false);
    pipeline->deactivate();
    cycles = scheduler.stats().cycles.load();
    if (result.faulted) std::fprintf(stderr, "local_control_server: fault: %s\n", result.fault.c_str());
  }
  (*server)->stop();
  const auto s = (*server)->stats();
  for (const auto& e : events.snapshot())
    std::fprintf(stderr, "event [%s] %s\n", e.kind.c_str(), e.text.c_str());
  std::printf("served: connections %llu requests %llu malformed %llu refused %llu cycles %llu\n",
              static_cast<unsigned long long>(s.connections), static_cast<unsigned long long>(s.requests),
              static_cast<unsigned long long>(s.malformed), static_cast<unsigned long long>(s.refused_clients),
              static_cast<unsigned long long>(cycles));
  return 0;
}
