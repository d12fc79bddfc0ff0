#include "lode/sdk/testing/require.hpp"

#include <cstdlib>
#include <filesystem>

namespace lode::testing {

std::string plugin_folder() {
  const char* path = std::getenv("LODE_PLUGIN_PATH");
  if (path == nullptr || *path == '\0') return LODE_BUILD_PLUGIN_DIR;
  const std::string list = path;
  return list.substr(0, list.find(':'));
}

bool plugin_built(std::string_view name) {
  return std::filesystem::exists(plugin_folder() + "/lode-" + std::string(name) + ".so");
}

std::string missing_plugins(std::initializer_list<std::string_view> names) {
  std::string missing;
  for (std::string_view name : names)
    if (!plugin_built(name)) missing += (missing.empty() ? "" : ", ") + std::string(name);
  return missing;
}

bool partial_plugin_build() noexcept { return plugin_selection()[0] != '\0'; }

const char* plugin_selection() noexcept { return LODE_PLUGIN_SELECTION; }

bool tools_required() noexcept { return LODE_REQUIRE_TEST_TOOLS != 0; }

}  // namespace lode::testing
