// libFuzzer target: the configuration loader's first pass (parse_config_yaml) on arbitrary
// text. Beyond "no crash, no sanitizer report, no time-out, no out-of-memory": a document it
// accepts must be a tree the rest of the loader can recurse over freely, no deeper than the
// depth limit and no larger than the node budget once aliases are expanded; and whatever it
// refuses, it says where.
#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "yaml_document.hpp"

namespace {

/// Counts nodes like a naive recursive loader would; aborts past the limits the check promises.
std::size_t walk(const YAML::Node& n, int depth) {
  if (depth > lode::detail::kMaxYamlDepth) std::abort();
  std::size_t count = 1;
  if (n.IsMap()) {
    for (const auto& kv : n) {
      if (!kv.first.IsScalar()) std::abort();  // refused by the check
      count += walk(kv.second, depth + 1);
    }
  } else if (n.IsSequence()) {
    for (const auto& e : n) count += walk(e, depth + 1);
  }
  if (count > lode::detail::kMaxYamlNodes + 1) std::abort();
  return count;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  lode::Diagnostics diagnostics;
  const auto root = lode::detail::parse_config_yaml(text, "fuzz.yaml", diagnostics);
  if (root) {
    if (!diagnostics.empty()) std::abort();
    walk(*root, 0);
  } else {
    if (diagnostics.empty()) std::abort();  // a refusal always says why
    for (const auto& d : diagnostics.items())
      if (d.where.file != "fuzz.yaml" || d.message.empty()) std::abort();
  }
  return 0;
}
