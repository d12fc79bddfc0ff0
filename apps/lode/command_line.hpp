// The `lode` command line: every command declares its options once (CLI11), in its own
// source file, so that `lode CMD --help` prints that command's usage and does nothing else,
// an unknown or misspelled option is an error naming it (with the nearest known one), and
// numbers, ranges and choices are checked before a command runs. The commands receive the
// parsed values (Args) and never see argv.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "cli.hpp"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace lode::cli {

/// Declares options on one command; each writes what it received into `args`, the one
/// structure the commands read.
class Declare {
 public:
  Declare(CLI::App* app, Args& args) : app_(app), args_(args) {}

  CLI::Option* text(const std::string& name, const std::string& value_name, const std::string& description);
  /// An integer in [min, max], written as digits: read it with Args::integer().
  CLI::Option* integer(const std::string& name, const std::string& value_name, const std::string& description,
                       long long min, long long max);
  /// A finite number in [min, max]: read it with Args::number().
  CLI::Option* number(const std::string& name, const std::string& value_name, const std::string& description,
                      double min, double max);
  CLI::Option* choice(const std::string& name, const std::vector<std::string>& choices,
                      const std::string& description);
  CLI::Option* flag(const std::string& name, const std::string& description);
  /// A repeatable option (`--config A --config B`): every value, in order, in Args::lists.
  CLI::Option* list(const std::string& name, const std::string& value_name, const std::string& description);
  /// Positional arguments, `min` to `max` of them, in order.
  CLI::Option* positional(const std::string& name, const std::string& description, int min, int max);

  /// Where a remote command finds its participants: --domain, --transport, --peers,
  /// --interfaces, --name (defaults from the LODE_DDS_* environment).
  void dds_options();
  /// set, swap and record --remote-*: the local socket of a pipeline on this host, else DDS.
  void command_route_options();

 private:
  CLI::App* app_;
  Args& args_;
};

/// One command: its name, what it does (the first line of its --help), its options, and
/// what it does with them (returns the exit code).
struct Command {
  std::string name;
  std::string description;
  std::function<void(Declare&)> declare;
  std::function<int(const Args&)> run;
  /// For bash completion of a positional argument: a bash command printing the words it may
  /// be (live names, asked where that is cheap). `$lode` is the program being completed and
  /// `$npos` the number of positional arguments before the word.
  std::string positional_words = {};
};

/// Parses argv against the command table, then runs the chosen command. Exit codes: 0, 1
/// (the command's fault) or 2 (usage: an unknown option, a bad value, a missing argument).
/// `lode --bash-completion` prints bash_completion(commands).
int run_command_line(int argc, char** argv, const std::vector<Command>& commands);

/// A bash completion script for `lode`, generated from the same declarations: commands,
/// each command's options, the choices of an option that has them, pipeline files (*.yaml)
/// or recordings (*.h5) where a command takes one, and for `set` and `swap` the names a
/// pipeline running on this host offers (asked over its local socket, no DDS).
std::string bash_completion(const std::vector<Command>& commands);

}  // namespace lode::cli
