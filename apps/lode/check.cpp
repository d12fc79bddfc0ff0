// lode check CONFIG: load and validate a pipeline; nothing is activated.
#include <cstdio>

#include "commands.hpp"
#include "load_config.hpp"
#include "reference_reach.hpp"

namespace lode::cli {

Command check_command() {
  return {"check", "validate a pipeline; every problem with file:line:column",
          [](Declare& d) { d.positional("CONFIG", "the pipeline file", 1, 1); },
          [](const Args& args) {
            const auto loaded = load_config(args.positional.at(0));
            if (!loaded) return kExitConfig;
            const auto& p = loaded->pipeline;
            std::printf("%s: ok: pipeline '%s' at %g Hz, %zu operations per cycle:", loaded->path.c_str(),
                        p->name().c_str(), p->rate_hz(), p->ops().size());
            for (const auto& op : p->ops()) std::printf(" %s", op.label.c_str());
            std::printf("\n");
            // Valid, yet certain to fault: a reference the envelope does not let the stage follow.
            for (const auto& w : reference_outside_envelope(*p))
              std::printf("%s: warning: %s\n", loaded->path.c_str(), w.c_str());
            return kExitOk;
          }};
}

}  // namespace lode::cli
