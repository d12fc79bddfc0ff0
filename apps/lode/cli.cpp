#include "cli.hpp"

#include <csignal>
#include <cstdlib>

namespace lode::cli {

std::atomic<bool>& stop_requested() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {
extern "C" void on_stop_signal(int) { stop_requested().store(true); }
}  // namespace

void install_stop_handlers() {
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  // The terminal went away (an ssh session dropped, the window closed): stop as on Ctrl-C,
  // outputs driven safe and files closed, rather than die where the default action would.
  std::signal(SIGHUP, on_stop_signal);
}

void ignore_broken_pipes() {
  // By default a write to a pipe whose reader has gone (`lode run ... | head`, `lode echo X |
  // grep -m1 Y`) kills the process on the spot: a pipeline's outputs not driven safe, its
  // recording not closed, and a telemetry client gone from inside its shared-memory receive
  // thread, which could leave the pipeline unreachable over shared memory to every client
  // after it. Ignored, the write fails with EPIPE instead and each command decides.
  std::signal(SIGPIPE, SIG_IGN);
}

double Args::number(const std::string& o, double fallback) const {
  const auto it = options.find(o);
  return it == options.end() ? fallback : std::strtod(it->second.c_str(), nullptr);
}

long long Args::integer(const std::string& o, long long fallback) const {
  const auto it = options.find(o);
  return it == options.end() ? fallback : std::strtoll(it->second.c_str(), nullptr, 10);
}

}  // namespace lode::cli
