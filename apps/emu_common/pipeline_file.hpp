// What a board emulator (lode-vme-emu, lode-can-emu) reads of a pipeline file: the file as
// YAML, the block of the board's plugin in it, and a block's parameters as lode::BlockHost
// takes them.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>

#include "lode/sdk/status.hpp"

namespace lode::emu {

/// The whole file as YAML; the error is yaml-cpp's own message.
Expected<YAML::Node> load_yaml_file(const std::string& file);

struct NamedBlock {
  std::string name;
  YAML::Node node;
};

/// The block of plugin `plugin` in the pipeline file `file`: the one named `name`, or with an
/// empty `name` the first. The error is yaml-cpp's when the file does not load, else "FILE has
/// no PLUGIN block" (and the name asked for).
Expected<NamedBlock> find_block(const std::string& file, const std::string& plugin, const std::string& name);

/// A block's own parameters as YAML text: its map without `plugin` and `inputs`, which are
/// the pipeline's business.
std::string block_params_text(const YAML::Node& block);

}  // namespace lode::emu
