#include "cli.hpp"

#include <csignal>
#include <cstdio>
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

std::optional<double> number_option(const Args& args, const std::string& name, double fallback, double min,
                                    double max) {
  if (!args.has(name)) return fallback;
  const std::string text = args.option(name);
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || !end || *end || !(v >= min && v <= max)) {
    std::fprintf(stderr, "lode: %s must be a number in [%g, %g], got '%s'\n", name.c_str(), min, max, text.c_str());
    return std::nullopt;
  }
  return v;
}

}  // namespace lode::cli
