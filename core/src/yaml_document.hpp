// Internal: parse configuration YAML into a tree every later pass can walk without a budget.
//
// yaml-cpp 0.7 resolves an alias by sharing the anchored node, so the parsed document is a
// graph, not a tree: `a: &r [1, *r]` is a cycle (a naive recursive walk overflows the stack)
// and nine nested levels of ten aliases each (the "billion laughs") expand to 10^9 nodes from
// a few kilobytes of text. parse_config_yaml() walks the graph once, bounded in depth and in
// expanded nodes, and also refuses what the loader cannot use: keys that are not scalars and
// duplicate keys (which yaml-cpp would silently collapse to the last one). Only a document that
// passes is returned, so the rest of the loader may recurse freely.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <optional>
#include <string>

#include "lode/sdk/diagnostics.hpp"

namespace lode::detail {

/// Deepest nesting accepted. A pipeline nests about six levels (blocks, block, parameter,
/// list, item, field); 64 leaves room for any real file and stops a recursive alias at once.
inline constexpr int kMaxYamlDepth = 64;
/// Most nodes a document may expand to, counting an aliased subtree at each use. The largest
/// shipped pipeline has about 600; a million is a 4 MiB calibration table's worth.
inline constexpr std::size_t kMaxYamlNodes = 1'000'000;

/// Parses `text`; every problem (syntax, depth, expansion, key form, duplicates) is added to
/// `diagnostics` with file `label`, line, column and field path. Returns the root only when
/// there was none.
std::optional<YAML::Node> parse_config_yaml(const std::string& text, const std::string& label,
                                            Diagnostics& diagnostics, int max_depth = kMaxYamlDepth,
                                            std::size_t max_nodes = kMaxYamlNodes);

}  // namespace lode::detail
