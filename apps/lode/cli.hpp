// Command-line plumbing shared by the `lode` subcommands.
#pragma once

#include <algorithm>
#include <atomic>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/status.hpp"

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
  /// A number option's value. The command line has already checked it against the range the
  /// option declares (command_line.hpp), so the range is written in one place only.
  [[nodiscard]] double number(const std::string& o, double fallback) const;
  /// An integer option's value (checked by the command line like number()).
  [[nodiscard]] long long integer(const std::string& o, long long fallback) const;
};

/// Set by SIGINT, SIGTERM and SIGHUP once install_stop_handlers() has run.
std::atomic<bool>& stop_requested();
void install_stop_handlers();
/// A write to a closed pipe fails with EPIPE instead of killing the process (for every command).
void ignore_broken_pipes();

/// Writes `text` to the file at `path` (created, or replaced in place) and closes it; an error
/// naming the path and the system's reason (a full disk, a missing folder, a read-only file)
/// when any of it did not reach the file.
Status write_text_file(const std::string& path, std::string_view text);

/// At the end of a command: `exit_code`, or kExitFault after saying so on stderr when what was
/// printed on standard output did not all reach it (`lode describe > file` on a full disk).
/// A reader that went away (EPIPE: `lode echo X | head`) is not an error.
int finish_standard_output(int exit_code);

}  // namespace lode::cli
