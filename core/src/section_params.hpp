// A top-level section of a pipeline file (realtime:, record:, monitor:, telemetry:) as the
// Params it is read through. Private to the core.
#pragma once

#include <yaml-cpp/yaml.h>

#include <optional>
#include <string>

#include "lode/sdk/diagnostics.hpp"
#include "lode/sdk/params.hpp"
#include "params_node.hpp"

namespace lode::detail {

/// The section's keys to read, or nothing when it is not a map: that is reported at its place
/// ("expected a map") and nothing of it is read.
inline std::optional<Params> section_params(const YAML::Node& node, const std::string& section,
                                            const std::string& file, Diagnostics* diagnostics) {
  if (!node.IsMap()) {
    diagnostics->add(location_of(node, file), section, "expected a map");
    return std::nullopt;
  }
  return make_params(node, section, file, diagnostics);
}

}  // namespace lode::detail
