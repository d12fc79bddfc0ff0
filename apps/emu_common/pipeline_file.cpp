#include "pipeline_file.hpp"

namespace lode::emu {

Expected<YAML::Node> load_yaml_file(const std::string& file) {
  try {
    return YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    return Status::error(e.what());
  }
}

Expected<NamedBlock> find_block(const std::string& file, const std::string& plugin, const std::string& name) {
  const auto loaded = load_yaml_file(file);
  if (!loaded) return loaded.status();
  YAML::Node root = *loaded;  // non-const: a missing key reads as an undefined node, not an invalid one
  for (const auto& kv : root["blocks"]) {
    if (kv.second["plugin"].as<std::string>("") != plugin) continue;
    if (!name.empty() && kv.first.as<std::string>() != name) continue;
    return NamedBlock{kv.first.as<std::string>(), kv.second};
  }
  return Status::error(file + " has no " + plugin + " block" + (name.empty() ? "" : " named '" + name + "'"));
}

std::string block_params_text(const YAML::Node& block) {
  YAML::Node params = YAML::Clone(block);
  params.remove("plugin");
  params.remove("inputs");
  YAML::Emitter text;
  text << params;
  return text.c_str();
}

}  // namespace lode::emu
