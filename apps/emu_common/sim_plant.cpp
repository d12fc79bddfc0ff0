#include "sim_plant.hpp"

#include <yaml-cpp/yaml.h>

#include "pipeline_file.hpp"

namespace lode::emu {

Expected<std::unique_ptr<SimPlant>> SimPlant::open(const std::string& sim_file, const std::string& block,
                                                   const Elements& command,
                                                   const std::vector<std::string>& signal_names) {
  const auto loaded = load_yaml_file(sim_file);
  if (!loaded) return Status::error(sim_file + ": " + loaded.error());
  YAML::Node root = *loaded;  // non-const: a missing key reads as an undefined node, not an invalid one
  const YAML::Node sim_block = root["blocks"][block];
  if (!sim_block || sim_block["plugin"].as<std::string>("") != "io.sim")
    return Status::error(sim_file + " has no io.sim block named '" + block + "'");
  YAML::Emitter models_text;
  models_text << root["models"];
  const double rate_hz = root["rate_hz"].as<double>(800.0);
  auto host = std::make_unique<BlockHost>("io.sim", block_params_text(sim_block), rate_hz, models_text.c_str());
  host->feed("command", command);
  if (auto st = host->configure(); !st)
    return Status::error("the io.sim block '" + block + "' of " + sim_file + " against the board's outputs:\n" +
                         st.message());
  const Elements& signals = host->output_elements("signals");
  if (signals.size() != signal_names.size())
    return Status::error("io.sim '" + block + "' of " + sim_file + " has " + std::to_string(signals.size()) +
                         " channels, the board " + std::to_string(signal_names.size()) + " inputs");
  for (std::size_t i = 0; i < signals.size(); ++i)
    if (signals[i].name != signal_names[i])
      return Status::error("input " + std::to_string(i) + " is '" + signal_names[i] + "' on the board but '" +
                           signals[i].name + "' in io.sim '" + block + "' of " + sim_file);
  if (auto st = host->activate(); !st) return st;
  return std::unique_ptr<SimPlant>(new SimPlant(std::move(host), rate_hz));
}

std::span<const double> SimPlant::sample_after(std::span<const double> command) {
  if (!first_) {
    auto in = host_->input("command");
    for (std::size_t i = 0; i < in.size() && i < command.size(); ++i) in[i] = command[i];
    if (host_->write() != StepStatus::ok) ++faults_;
  }
  first_ = false;
  if (host_->step() != StepStatus::ok) ++faults_;
  return host_->output("signals");
}

}  // namespace lode::emu
