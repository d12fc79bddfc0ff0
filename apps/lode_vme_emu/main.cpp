// lode-vme-emu: plays the Pentek-like VME board pair of io.vme_pentek on a shared-memory
// register window, its ADC inputs driven by the io.sim block of a simulation pipeline (the
// plant, the measurement models and the acquisition chain's noise), its DAC outputs driving
// that plant. So a whole closed loop runs over the register interface without hardware.
//
//   lode-vme-emu BOARD.yaml --sim SIM.yaml [--block NAME] [--spin]
//
// BOARD.yaml is the pipeline that uses io.vme_pentek (the window's device and offset, the
// register map and the channels are taken from its block, `register_map` resolved as
// io.vme_pentek resolves it: relative to BOARD.yaml's directory); SIM.yaml has an io.sim block of the same name (or
// --block NAME) whose `signals` are the ADC channels and whose `command` the DAC channels,
// in order, with the same names and units. Per trigger the emulator advances the plant by one
// period under the DAC values latched so far, samples it, and presents the codes: the same
// timing as io.sim in a pipeline (the sample of cycle k+1 is the first to show the command of
// cycle k). Stops on SIGINT/SIGTERM. Exit codes: 0 stopped, 2 configuration error.
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <chrono>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "emulator.hpp"
#include "lode/hal/analog.hpp"
#include "lode/sdk/units.hpp"
#include "pipeline_file.hpp"
#include "regmap.hpp"
#include "sim_plant.hpp"

namespace {

constexpr int kExitConfig = 2;
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

struct BoardConfig {
  std::string device;
  std::uint64_t offset = 0;
  std::string register_map;  ///< "" = the built-in map
  lode::vme::Layout layout = lode::vme::Layout::default_layout();
  std::vector<lode::hal::AnalogChannel> adc, dac;
};

std::string where(const std::string& file, const YAML::Node& n) {
  return file + ":" + std::to_string(n.Mark().line + 1);
}

/// The io.vme_pentek block's channels, read as io.vme_pentek reads them (same defaults).
bool read_channels(const std::string& file, const YAML::Node& list, bool output,
                   std::vector<lode::hal::AnalogChannel>& out) {
  for (const auto& item : list) {
    lode::hal::AnalogChannel c;
    c.name = item["name"].as<std::string>("");
    c.bits = item["bits"].as<int>(16);
    if (item["span_v"]) {
      c.span_min_v = item["span_v"][0].as<double>();
      c.span_max_v = item["span_v"][1].as<double>();
    }
    const std::string coding = item["coding"].as<std::string>("twos_complement");
    c.coding = coding == "offset_binary" ? lode::hal::Coding::offset_binary
               : coding == "unipolar"    ? lode::hal::Coding::unipolar
                                         : lode::hal::Coding::twos_complement;
    c.gain = item["gain"].as<double>(1.0);
    c.offset = item["offset"].as<double>(0.0);
    c.unit = lode::canonical_unit(item["unit"].as<std::string>("V"));
    if (output) c.safe_value = item["safe_value"].as<double>(0.0);
    if (auto st = lode::hal::validate(c); !st) {
      std::fprintf(stderr, "lode-vme-emu: %s: %s\n", where(file, item).c_str(), st.message().c_str());
      return false;
    }
    out.push_back(c);
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string board_file, sim_file, block;
  bool spin = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sim" && i + 1 < argc) sim_file = argv[++i];
    else if (a == "--block" && i + 1 < argc) block = argv[++i];
    else if (a == "--spin") spin = true;
    else if (a == "-h" || a == "--help") {
      std::printf(
          "usage: lode-vme-emu BOARD.yaml --sim SIM.yaml [--block NAME] [--spin]\n"
          "\n"
          "Plays the Pentek-like VME board pair of an io.vme_pentek block on its register window (a\n"
          "shared file), the ADC inputs driven by the io.sim block of SIM.yaml (plant, sensors, noise)\n"
          "and the DAC outputs driving that plant: a closed loop over the register interface without\n"
          "the hardware. Start it before `lode run BOARD.yaml`; stop it with Ctrl-C.\n"
          "\n"
          "  BOARD.yaml     the pipeline with the io.vme_pentek block (window, register map, channels)\n"
          "  --sim SIM.yaml a pipeline with an io.sim block of the same name: its signals are the ADC\n"
          "                 channels, its command the DAC channels, in order, same names and units\n"
          "  --block NAME   which block of both files (default: the first io.vme_pentek one)\n"
          "  --spin         poll the trigger register without sleeping (pin it to a CPU of its own)\n"
          "\n"
          "exit codes: 0 stopped, 2 configuration error. See docs/hardware.md.\n");
      return 0;
    } else if (board_file.empty() && a[0] != '-') board_file = a;
    else {
      std::fprintf(stderr, "lode-vme-emu: unknown argument '%s' (--help)\n", a.c_str());
      return kExitConfig;
    }
  }
  if (board_file.empty() || sim_file.empty()) {
    std::fprintf(stderr, "usage: lode-vme-emu BOARD.yaml --sim SIM.yaml [--block NAME] [--spin]\n");
    return kExitConfig;
  }
  // The board: the io.vme_pentek block (named --block, else the first).
  auto found = lode::emu::find_block(board_file, "io.vme_pentek", block);
  if (!found) {
    std::fprintf(stderr, "lode-vme-emu: %s\n", found.error().c_str());
    return kExitConfig;
  }
  block = found->name;
  YAML::Node vme = found->node;
  BoardConfig board;
  board.device = vme["device"].as<std::string>("");
  board.offset = vme["offset"].as<std::uint64_t>(0);
  // The same map as io.vme_pentek: a relative path is relative to BOARD.yaml's directory
  // (lode::Params::file_path), so both sides agree wherever they are started from.
  board.register_map = vme["register_map"].as<std::string>("");
  if (!board.register_map.empty()) {
    const std::filesystem::path map(board.register_map);
    if (map.is_relative())
      board.register_map = (std::filesystem::path(board_file).parent_path() / map).lexically_normal().string();
    auto layout = lode::vme::load_layout(board.register_map);
    if (!layout) {
      std::fprintf(stderr, "lode-vme-emu: %s: register_map of block '%s':\n%s\n",
                   where(board_file, vme["register_map"]).c_str(), block.c_str(), layout.error().c_str());
      return kExitConfig;
    }
    board.layout = *layout;
  }
  if (!read_channels(board_file, vme["adc"], false, board.adc) || !read_channels(board_file, vme["dac"], true, board.dac))
    return kExitConfig;
  // The plant side: the io.sim block of the same name in the simulation pipeline, its command
  // the DAC channels and its signals the ADC channels (names checked by SimPlant).
  lode::Elements command;
  for (const auto& c : board.dac) command.push_back({c.name, c.unit});
  std::vector<std::string> adc_names;
  for (const auto& c : board.adc) adc_names.push_back(c.name);
  auto plant = lode::emu::SimPlant::open(sim_file, block, command, adc_names);
  if (!plant) {
    std::fprintf(stderr, "lode-vme-emu: %s\n", plant.error().c_str());
    return kExitConfig;
  }
  // ADC: the converter codes of the io.sim volts (no calibration: the board converts volts).
  std::vector<lode::hal::AnalogConversion> adc_volts, dac_values;
  for (auto c : board.adc) {
    c.gain = 1.0;
    c.offset = 0.0;
    adc_volts.emplace_back(c);
  }
  for (const auto& c : board.dac) dac_values.emplace_back(c);
  std::vector<double> dac_command(board.dac.size(), 0.0);
  auto frontend = [&](const std::vector<std::uint32_t>& dac, std::vector<std::uint32_t>& adc) {
    // One period under the DAC values latched so far (skipped on the first trigger), then the sample.
    for (std::size_t i = 0; i < dac.size(); ++i) dac_command[i] = dac_values[i].code_to_value(dac[i]);
    const auto volts = (*plant)->sample_after(dac_command);
    for (std::size_t i = 0; i < adc.size(); ++i) {
      bool clipped = false;
      adc[i] = adc_volts[i].value_to_code(volts[i], clipped);
    }
  };
  // The emulator creates the board's file when there is none; it removes what it created
  // when it stops, so no stale board is left for the next run to open.
  struct stat before {};
  const bool created_here = ::stat(board.device.c_str(), &before) != 0 && errno == ENOENT;
  auto emulator = lode::vme::PentekEmulator::create(board.device, board.offset, board.layout, board.adc.size(),
                                                    board.dac.size(), frontend);
  if (!emulator) {
    std::fprintf(stderr, "lode-vme-emu: %s\n", emulator.error().c_str());
    return kExitConfig;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::printf("lode-vme-emu: serving %s @ 0x%llx (%zu ADC, %zu DAC channels, register map %s), plant from io.sim '%s' of %s\n",
              board.device.c_str(), static_cast<unsigned long long>(board.offset), board.adc.size(), board.dac.size(),
              board.register_map.empty() ? "built-in" : board.register_map.c_str(), block.c_str(), sim_file.c_str());
  std::fflush(stdout);
  auto& e = **emulator;
  while (!g_stop.load()) {
    if (!e.poll() && !spin) std::this_thread::sleep_for(std::chrono::microseconds(10));
  }
  std::printf("lode-vme-emu: stopped after %llu conversions, %llu DAC loads, %llu plant faults\n",
              static_cast<unsigned long long>(e.conversions()), static_cast<unsigned long long>(e.dac_loads()),
              static_cast<unsigned long long>((*plant)->faults()));
  emulator->reset();
  if (created_here) ::unlink(board.device.c_str());
  return 0;
}
