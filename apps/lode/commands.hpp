// The `lode` commands, one source file each. main.cpp lists them in the order `lode --help`
// shows them.
#pragma once

#include "command_line.hpp"

namespace lode::cli {

Command run_command();
Command check_command();
Command describe_command();
Command plugins_command();
Command replay_command();
Command plot_command();
Command bench_command();
Command rtcheck_command();
Command topics_command();
Command echo_command();
Command record_command();
Command set_command();
Command swap_command();
Command scope_command();

}  // namespace lode::cli
