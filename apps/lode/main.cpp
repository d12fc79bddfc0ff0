// lode: run, check and inspect lodestone pipelines; watch and command them over Fast DDS.
//
// Exit codes: 0 success, 1 runtime fault, 2 invalid configuration (or usage).
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>
#include <vector>

#include "cli.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  using namespace lode::cli;
  ignore_broken_pipes();
  const std::vector<Command> commands = {run_command(),    check_command(),  describe_command(), plugins_command(),
                                         replay_command(), plot_command(),   bench_command(),    rtcheck_command(),
                                         topics_command(), echo_command(),   record_command(),   set_command(),
                                         swap_command(),   scope_command()};
  try {
    return finish_standard_output(run_command_line(argc, argv, commands));
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "lode: internal error: %s\n", ex.what());
    return kExitFault;
  }
}
