// Turning a pipeline into a replay of a recording: every io block becomes io.replay.
#include <yaml-cpp/yaml.h>

#include <algorithm>

#include "replay.hpp"

namespace lode::cli {

std::string rewrite_for_replay(const std::string& yaml, const std::string& recording, PluginRegistry& registry,
                               std::vector<std::string>& replaced, std::string& note) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception&) {
    return yaml;  // the loader reports the syntax error at its place
  }
  if (!root.IsMap() || !root["blocks"] || !root["blocks"].IsMap()) return yaml;
  const YAML::Node blocks = root["blocks"];

  // Lines of the text (without their '\n').
  std::vector<std::string> lines;
  {
    std::size_t start = 0;
    for (;;) {
      const auto nl = yaml.find('\n', start);
      lines.push_back(yaml.substr(start, nl == std::string::npos ? std::string::npos : nl - start));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
  std::vector<int> top_lines;
  for (const auto& kv : root) top_lines.push_back(kv.first.Mark().line);
  std::vector<int> block_lines;
  for (const auto& kv : blocks) block_lines.push_back(kv.first.Mark().line);

  struct Edit {
    int first = 0, end = 0;  // [first, end) lines
    std::string text;
  };
  std::vector<Edit> edits;
  bool whole = false;
  std::size_t index = 0;
  for (auto it = blocks.begin(); it != blocks.end(); ++it, ++index) {
    const std::string name = it->first.as<std::string>();
    const YAML::Node spec = it->second;
    if (!spec.IsMap() || !spec["plugin"] || !spec["plugin"].IsScalar()) continue;
    auto plugin = registry.find(spec["plugin"].Scalar());
    if (!plugin || plugin->descriptor->kind != PluginKind::io) continue;
    replaced.push_back(name);

    YAML::Emitter e;
    e << YAML::Flow << YAML::BeginMap;
    e << YAML::Key << "plugin" << YAML::Value << "io.replay";
    e << YAML::Key << "recording" << YAML::Value << YAML::DoubleQuoted << recording;
    e << YAML::Key << "block" << YAML::Value << name;
    if (spec["inputs"]) e << YAML::Key << "inputs" << YAML::Value << YAML::Flow << spec["inputs"];
    e << YAML::EndMap;

    const int first = it->first.Mark().line;
    int end = static_cast<int>(lines.size());
    if (index + 1 < block_lines.size()) {
      end = block_lines[index + 1];
    } else {
      for (const int t : top_lines)
        if (t > first) {
          end = t;
          break;
        }
    }
    // A flow-style `blocks:` puts several blocks on one line: no line-preserving edit.
    if (end <= first || first < 0 || static_cast<std::size_t>(first) >= lines.size()) whole = true;
    YAML::Emitter key;
    key << name;
    const std::string indent(static_cast<std::size_t>(std::max(0, it->first.Mark().column)), ' ');
    edits.push_back({first, end, indent + key.c_str() + ": " + e.c_str()});
  }
  if (edits.empty()) return yaml;

  if (whole) {
    YAML::Node copy = YAML::Clone(root);
    for (const auto& name : replaced) {
      YAML::Node spec = copy["blocks"][name];
      YAML::Node r;
      r["plugin"] = "io.replay";
      r["recording"] = recording;
      r["block"] = name;
      if (spec["inputs"]) r["inputs"] = spec["inputs"];
      copy["blocks"][name] = r;
    }
    YAML::Emitter e;
    e << copy;
    note = "the configuration was rewritten as a whole (flow-style blocks:): line numbers refer to the rewritten text";
    return std::string(e.c_str()) + "\n";
  }
  for (const auto& ed : edits) {
    lines[static_cast<std::size_t>(ed.first)] = ed.text;
    for (int l = ed.first + 1; l < ed.end; ++l) lines[static_cast<std::size_t>(l)].clear();
  }
  std::string out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    out += lines[i];
    if (i + 1 < lines.size()) out += '\n';
  }
  return out;
}

}  // namespace lode::cli
