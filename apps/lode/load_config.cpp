#include "load_config.hpp"

#include <cstdio>

#include "lode/sdk/diagnostics.hpp"

namespace lode::cli {

std::optional<LoadedConfig> load_config(const std::string& path) {
  LoadedConfig loaded;
  loaded.path = path;
  loaded.registry = std::make_unique<PluginRegistry>();
  Diagnostics diag;
  loaded.pipeline = Pipeline::load_file(loaded.path, *loaded.registry, diag);
  if (!loaded.pipeline) {
    std::fputs(diag.format().c_str(), stderr);
    std::fprintf(stderr, "lode: %zu problem%s in %s; nothing was started\n", diag.size(),
                 diag.size() == 1 ? "" : "s", loaded.path.c_str());
    return std::nullopt;
  }
  return loaded;
}

}  // namespace lode::cli
