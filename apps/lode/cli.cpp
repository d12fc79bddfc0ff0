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
