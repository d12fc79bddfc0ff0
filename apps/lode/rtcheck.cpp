// lode rtcheck: what this host offers a real-time run (kernel, limits, CPUs), as JSON.
#include <iostream>

#include "commands.hpp"
#include "lode/realtime.hpp"

namespace lode::cli {

Command rtcheck_command() {
  return {"rtcheck", "how fit this host is for real-time runs, with advice", [](Declare&) {},
          [](const Args&) {
            std::cout << realtime_host_report().dump() << "\n";
            return kExitOk;
          }};
}

}  // namespace lode::cli
