// lode topics: the lodestone topics live on the domain, with rates, element names and units
// (from the transient-local lode/signals topic, so a late joiner sees them all).
#include <cstdio>
#include <set>
#include <thread>

#include "commands.hpp"
#include "remote_client.hpp"

namespace lode::cli {
namespace {

int topics(const Args& args) {
  auto client = make_client(args, "topics");
  if (!client) return kExitConfig;
  auto signals = client->signals(wait_option(args, 2.0));
  // Metadata arrives topic by topic: once the first is in, give the rest a moment.
  if (!signals.empty()) {
    std::this_thread::sleep_for(milliseconds(500));
    signals = client->signals(milliseconds(0));
  }
  if (signals.empty()) {
    std::fprintf(stderr, "lode: no lodestone topic seen within the wait (is a pipeline with `telemetry:` running on this domain?)\n");
    return kExitFault;
  }
  const bool json = args.has_flag("--json");
  std::set<std::string> pipelines;
  if (json) std::printf("[\n");
  for (std::size_t i = 0; i < signals.size(); ++i) {
    const auto& s = signals[i];
    pipelines.insert(s.pipeline);
    if (json) {
      std::printf("  {\"topic\": \"%s\", \"pipeline\": \"%s\", \"kind\": \"%s\", \"rate_hz\": %.17g, \"names\": [",
                  s.topic.c_str(), s.pipeline.c_str(), s.kind.c_str(), s.rate_hz);
      for (std::size_t k = 0; k < s.names.size(); ++k)
        std::printf("%s\"%s\"", k ? ", " : "", s.names[k].c_str());
      std::printf("], \"units\": [");
      for (std::size_t k = 0; k < s.units.size(); ++k)
        std::printf("%s\"%s\"", k ? ", " : "", s.units[k].c_str());
      std::printf("]}%s\n", i + 1 < signals.size() ? "," : "");
      continue;
    }
    std::string elements;
    for (std::size_t k = 0; k < s.names.size(); ++k)
      elements += (k ? " " : "") + s.names[k] + unit_suffix(k < s.units.size() ? s.units[k] : "");
    std::printf("%-44s %9.6g Hz  %s\n", s.topic.c_str(), s.rate_hz, elements.c_str());
  }
  if (json) {
    std::printf("]\n");
  } else {
    for (const auto& p : pipelines) {
      std::printf("%-44s events (faults, parameter changes, swaps, start/stop)\n", pipeline_topic(p, "events").c_str());
      std::printf("%-44s timing statistics\n", pipeline_topic(p, "timing").c_str());
    }
  }
  return kExitOk;
}

}  // namespace

Command topics_command() {
  return {"topics", "the live lodestone topics with rates, element names and units",
          [](Declare& d) {
            d.flag("--json", "as JSON");
            d.number("--wait", "S", "how long to listen (default 2)", 0, 3600);
            d.dds_options();
          },
          topics};
}

}  // namespace lode::cli
