// Loading the pipeline file a command names (run, check, describe, bench).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace lode::cli {

/// A loaded pipeline with the registry whose libraries its blocks live in (declared first:
/// destroyed last).
struct LoadedConfig {
  std::unique_ptr<PluginRegistry> registry;
  std::unique_ptr<Pipeline> pipeline;
  std::string path;
};

/// Loads `path`; prints every diagnostic (file:line:column: field: message) and returns
/// nullopt when there is nothing to run.
std::optional<LoadedConfig> load_config(const std::string& path);

}  // namespace lode::cli
