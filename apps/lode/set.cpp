// lode set [PIPELINE/]BLOCK.PARAM [VALUE] | --list: change or read a runtime parameter of a
// running pipeline. The pipeline checks the value (number, range, allow-lists) and applies it
// at the next cycle boundary; the reply says what happened (old -> new at cycle N).
#include <cstdio>

#include "commands.hpp"
#include "remote_client.hpp"

namespace lode::cli {
namespace {

int set(const Args& args) {
  const bool list = args.has_flag("--list");
  if ((!list && (args.positional.empty() || args.positional.size() > 2)) || (list && args.positional.size() > 1)) {
    std::fprintf(stderr, "usage: lode set [PIPELINE/]BLOCK.PARAM VALUE   (set)\n"
                         "       lode set [PIPELINE/]BLOCK.PARAM         (read the value in force)\n"
                         "       lode set --list [[PIPELINE/]BLOCK]      (runtime parameters and ranges)\n"
                         "       [--pipeline NAME] [--local | --dds] [--timeout S]\n");
    return kExitConfig;
  }
  const std::string target = args.positional.empty() ? "" : args.positional[0];
  return send_command(args, "set", target, [&](const std::string& t) -> std::optional<ControlRequest> {
    ControlRequest r;
    if (list) {
      r.kind = "list";
      r.block = t;
      return r;
    }
    const auto dot = t.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == t.size()) {
      std::fprintf(stderr, "lode: expected BLOCK.PARAM, got '%s'\n", t.c_str());
      return std::nullopt;
    }
    r.block = t.substr(0, dot);
    r.name = t.substr(dot + 1);
    r.kind = args.positional.size() == 2 ? "set" : "get";
    if (args.positional.size() == 2) r.value = args.positional[1];
    return r;
  });
}

}  // namespace

Command set_command() {
  return {"set", "change (or read) a runtime parameter of a running pipeline; the reply says what happened",
          [](Declare& d) {
            d.positional("TARGET", "[PIPELINE/]BLOCK.PARAM [VALUE], or with --list an optional BLOCK", 0, 2);
            d.flag("--list", "list the runtime parameters (of BLOCK)");
            d.command_route_options();
            d.dds_options();
          },
          set,
          // The parameters of the pipeline running on this host, over its local socket (no DDS).
          R"($lode set --list --local --timeout 1 2>/dev/null | awk '$1 ~ /[.]/ { print $1 }')"};
}

}  // namespace lode::cli
