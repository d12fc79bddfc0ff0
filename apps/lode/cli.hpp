// Command-line plumbing shared by the `lode` subcommands.
#pragma once

#include <algorithm>
#include <atomic>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lode::cli {

constexpr int kExitOk = 0;
constexpr int kExitFault = 1;   ///< runtime fault, refused command, nothing received
constexpr int kExitConfig = 2;  ///< invalid configuration or usage

struct Args {
  std::string command;
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;
  std::vector<std::string> flags;
  std::map<std::string, std::vector<std::string>> lists;  ///< repeatable options, every value in order
  [[nodiscard]] bool has_flag(const std::string& f) const {
    return std::find(flags.begin(), flags.end(), f) != flags.end();
  }
  [[nodiscard]] bool has(const std::string& o) const { return options.count(o) != 0; }
  [[nodiscard]] std::string option(const std::string& o, const std::string& fallback = "") const {
    auto it = options.find(o);
    return it == options.end() ? fallback : it->second;
  }
};

/// Parse a number option; prints the problem and returns nullopt when malformed.
std::optional<double> number_option(const Args& args, const std::string& name, double fallback, double min,
                                    double max);

/// Set by SIGINT/SIGTERM.
std::atomic<bool>& stop_requested();
void install_stop_handlers();

int cmd_topics(const Args& args);
int cmd_echo(const Args& args);
int cmd_record(const Args& args);
int cmd_set(const Args& args);
int cmd_swap(const Args& args);

}  // namespace lode::cli
