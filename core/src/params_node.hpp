// Internal: the YAML behind lode::Params, and the bookkeeping of which keys were read.
#pragma once

#include <yaml-cpp/yaml.h>

#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "lode/sdk/diagnostics.hpp"
#include "lode/sdk/params.hpp"

namespace lode::detail {

/// Shared by every node of one parameter tree (one block or model).
struct ParamsTree {
  Diagnostics* diagnostics = nullptr;  ///< where problems go (owned by the loader)
  std::string file;
  std::size_t errors = 0;
  /// Fields already reported as missing or unreadable ("2 kg" where a number goes): what a
  /// plugin says of their stand-in value afterwards is a consequence (a missing `q` is then
  /// "expected 3 numbers, got 0", then "must be > 0" for each axis) and is not reported.
  std::set<std::string> unusable_fields;
  /// Every (field, message) reported, so that the same problem is said once.
  std::set<std::pair<std::string, std::string>> reported;
  /// Every map node handed out, kept alive until report_unread_keys() so that maps a plugin
  /// read through a temporary (items(), child()) are still checked. report_unread_keys()
  /// clears it, which also breaks the node -> tree -> node reference cycle.
  std::vector<std::shared_ptr<ParamsNode>> maps;
};

struct ParamsNode {
  YAML::Node node;
  std::string path;
  std::shared_ptr<ParamsTree> tree;
  std::set<std::string> read_keys;
};

SourceLocation location_of(const YAML::Node& node, const std::string& file);

/// Wrap a YAML map. `ignored_keys` are treated as read (e.g. "plugin", "inputs").
Params make_params(const YAML::Node& map, std::string path, std::string file,
                   Diagnostics* diagnostics, const std::vector<std::string>& ignored_keys = {});

/// Report keys of every map in the tree that configure() never read; call once per tree.
void report_unread_keys(const Params& root);

/// Top-level keys read by configure() (for the descriptor cross-check).
std::set<std::string> read_top_level_keys(const Params& root);

std::size_t error_count(const Params& root);

}  // namespace lode::detail
