// The `lode` command line: every command and its options declared once (CLI11), so that
// `lode CMD --help` prints that command's usage and does nothing else, an unknown or
// misspelled option is an error naming it (with the nearest known one), and numbers, ranges
// and choices are checked before a command runs. The commands themselves receive the parsed
// values (Args) and never see argv.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "cli.hpp"

namespace lode::cli {

/// What a command does with its parsed arguments; returns the exit code.
using CommandFunction = std::function<int(const Args&)>;

/// One entry of the command table.
struct CommandEntry {
  std::string name;
  CommandFunction run;
};

/// Parses argv against the command table, then runs the chosen command. Exit codes: 0, 1
/// (the command's fault) or 2 (usage: an unknown option, a bad value, a missing argument).
int run_command_line(int argc, char** argv, const std::vector<CommandEntry>& commands);

/// A bash completion script for `lode`, generated from the same declarations: commands,
/// each command's options, the choices of an option that has them, and pipeline files
/// (*.yaml) or recordings (*.h5) where a command takes one. `lode --bash-completion` prints it.
std::string bash_completion();

}  // namespace lode::cli
