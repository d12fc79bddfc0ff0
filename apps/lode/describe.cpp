// lode describe CONFIG: the resolved pipeline as JSON (order, bindings, every derived
// quantity a block reports through describe()).
#include <iostream>

#include "commands.hpp"
#include "load_config.hpp"

namespace lode::cli {

Command describe_command() {
  return {"describe", "the resolved pipeline as JSON, with every derived quantity",
          [](Declare& d) { d.positional("CONFIG", "the pipeline file", 1, 1); },
          [](const Args& args) {
            const auto loaded = load_config(args.positional.at(0));
            if (!loaded) return kExitConfig;
            std::cout << loaded->pipeline->describe().dump() << "\n";
            return kExitOk;
          }};
}

}  // namespace lode::cli
