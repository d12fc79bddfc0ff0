// lode swap [PIPELINE/]BLOCK PLUGIN | --promote SHADOW: exchange an estimator of a running
// pipeline (the newcomer is configured and checked off the RT thread; the state is handed
// over at one cycle boundary), or make a shadow the primary.
#include <cstdio>

#include "commands.hpp"
#include "lode/hot_swap.hpp"
#include "remote_client.hpp"

namespace lode::cli {
namespace {

int swap(const Args& args) {
  const bool promote = args.has("--promote");
  if ((!promote && args.positional.size() != 2) || (promote && !args.positional.empty() && args.positional.size() != 1)) {
    std::fprintf(stderr, "usage: lode swap [PIPELINE/]BLOCK PLUGIN [--params '{key: value, ...}'] [--shadow-cycles N] [--cold]\n"
                         "       lode swap --promote [PIPELINE/]SHADOW\n"
                         "       [--pipeline NAME] [--local | --dds] [--timeout S]\n");
    return kExitConfig;
  }
  const std::string target = promote ? args.option("--promote") : args.positional[0];
  const auto shadow_cycles = static_cast<std::uint64_t>(args.integer("--shadow-cycles", 0));
  return send_command(args, "swap", target, [&](const std::string& t) -> std::optional<ControlRequest> {
    if (promote) {
      ControlRequest r = promote_command(t);
      r.block = args.positional.empty() ? "" : args.positional[0];
      return r;
    }
    SwapRequest s;
    s.block = t;
    s.plugin = args.positional[1];
    s.params = args.option("--params");
    if (args.has("--shadow-cycles")) s.shadow_cycles = static_cast<std::uint32_t>(args.integer("--shadow-cycles", 0));
    s.warm_start = !args.has_flag("--cold");
    return swap_command(s);
  }, promote ? 0 : shadow_cycles);
}

}  // namespace

Command swap_command() {
  return {"swap",
          "hot-swap an estimator of a running pipeline (state handed over at a cycle boundary) or promote a shadow",
          [](Declare& d) {
            d.positional("ARGS", "[PIPELINE/]BLOCK PLUGIN: the block and the plugin to swap in", 0, 2);
            d.text("--params", "'{k: v}'", "the new block's parameters (YAML flow map)");
            d.integer("--shadow-cycles", "N", "run the newcomer as a shadow for N cycles first", 0, 100000000);
            d.flag("--cold", "no state handover");
            d.text("--promote", "SHADOW", "promote a shadow to the running estimator");
            d.command_route_options();
            d.dds_options();
          },
          swap,
          // The second word is the plugin to swap in: the installed estimators.
          R"([ "$npos" -eq 1 ] && $lode plugins 2>/dev/null | awk '/^estimator[.]/ { print $1 }')"};
}

}  // namespace lode::cli
