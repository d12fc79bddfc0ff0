// lode plugins [NAME] [--json]: the installed plugins with their parameters and ports (the
// catalogue in docs/plugins.md is generated from --json).
#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "lode/sdk/json.hpp"
#include "lode/plugin_loader.hpp"

namespace lode::cli {
namespace {

int list_plugins(const Args& args) {
  PluginRegistry reg;
  auto listing = reg.discover_all();
  if (!args.positional.empty()) {  // `lode plugins NAME`: that plugin only
    const std::string& wanted = args.positional.front();
    std::erase_if(listing.plugins, [&](const auto& p) { return wanted != p.descriptor->name; });
    if (listing.plugins.empty()) {
      std::fprintf(stderr, "lode: no plugin named '%s' (`lode plugins` lists them)\n", wanted.c_str());
      return kExitConfig;
    }
  }
  Json out = Json::array();
  for (const auto& p : listing.plugins) {
    const auto* d = p.descriptor;
    Json j = Json::object();
    j["name"] = d->name;
    j["kind"] = to_string(d->kind);
    j["version"] = d->version;
    j["summary"] = d->summary;
    j["file"] = p.path;
    Json params = Json::array();
    for (std::size_t i = 0; i < d->param_count; ++i) {
      Json pj = Json::object();
      pj["name"] = d->params[i].name;
      pj["type"] = d->params[i].type;
      pj["default"] = d->params[i].default_value ? Json(d->params[i].default_value) : Json();
      pj["description"] = d->params[i].description;
      params.push(std::move(pj));
    }
    j["parameters"] = std::move(params);
    Json ports = Json::array();
    for (std::size_t i = 0; i < d->port_count; ++i) {
      Json pj = Json::object();
      pj["name"] = d->ports[i].name;
      pj["direction"] = d->ports[i].direction;
      pj["description"] = d->ports[i].description;
      ports.push(std::move(pj));
    }
    j["ports"] = std::move(ports);
    out.push(std::move(j));
  }
  if (args.has_flag("--json")) {
    std::cout << out.dump() << "\n";
  } else {
    for (const auto& p : listing.plugins) {
      const auto* d = p.descriptor;
      std::printf("%-26s %-7s %-8s %s\n", d->name, to_string(d->kind), d->version, d->summary);
      for (std::size_t i = 0; i < d->port_count; ++i)
        std::printf("    %-4s %-18s %s\n", d->ports[i].direction, d->ports[i].name, d->ports[i].description);
      for (std::size_t i = 0; i < d->param_count; ++i) {
        const auto& pd = d->params[i];
        std::printf("    %-23s %-13s %-12s %s\n", pd.name, pd.type,
                    pd.default_value ? pd.default_value : "(required)", pd.description);
      }
    }
    std::printf("%zu plugin%s\n", listing.plugins.size(), listing.plugins.size() == 1 ? "" : "s");
  }
  for (const auto& e : listing.errors) std::fprintf(stderr, "lode: %s\n", e.c_str());
  return listing.errors.empty() ? kExitOk : kExitFault;
}

}  // namespace

Command plugins_command() {
  return {"plugins", "installed plugins with their parameters and ports",
          [](Declare& d) {
            d.positional("NAME", "show this plugin only (e.g. filter.biquad)", 0, 1);
            d.flag("--json", "as JSON");
          },
          list_plugins};
}

}  // namespace lode::cli
