// Finding and loading plugins (dlopen), with clear errors.
//
// A plugin named "estimator.glsdc" lives in a file "lode-estimator.glsdc.so" in one of the
// folders of the search path: $LODE_PLUGIN_PATH (colon-separated, first: it overrides), then
// the installed plugin folder relative to the program's, then the build tree's <exe>/../plugins.
// Libraries stay loaded for the life of the registry (plugins' objects must never outlive
// their code, and dlclose of C++ code is a classic source of shutdown crashes).
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/status.hpp"

namespace lode {

struct LoadedPlugin {
  const PluginDescriptor* descriptor = nullptr;
  std::string path;
};

class PluginRegistry {
 public:
  explicit PluginRegistry(std::vector<std::string> search_path = default_search_path());

  static std::vector<std::string> default_search_path();
  [[nodiscard]] const std::vector<std::string>& search_path() const { return search_path_; }

  /// Load (once) the plugin with this name from the search path.
  Expected<LoadedPlugin> find(const std::string& name);
  /// Load a specific file; checks the symbol and the ABI version.
  Expected<LoadedPlugin> load_file(const std::string& path);
  /// Every plugin file on the search path (first one wins per name), with load errors.
  struct Listing {
    std::vector<LoadedPlugin> plugins;
    std::vector<std::string> errors;
  };
  Listing discover_all();

 private:
  std::vector<std::string> search_path_;
  std::mutex mutex_;
  std::map<std::string, LoadedPlugin> by_name_;
  std::map<std::string, LoadedPlugin> by_path_;
};

}  // namespace lode
