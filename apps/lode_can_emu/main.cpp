// lode-can-emu: plays the CANopen DAQ module of an io.socketcan_daq block on a CAN interface
// (vcan0, can0), its analog inputs (TPDOs) driven by the io.sim block of a simulation pipeline
// (the plant, the sensors, the acquisition noise), its analog outputs (RPDOs) driving that
// plant. So a whole closed loop runs over CAN frames without the module.
//
//   lode-can-emu BOARD.yaml --sim SIM.yaml [--block NAME] [--interface IF]
//                [--fault KIND --fault-after-syncs N] [--heartbeat-ms MS]
//
// BOARD.yaml is the pipeline that uses io.socketcan_daq: node id, PDO mappings, scales and the
// interface come from its block (named --block, else the first), read by the plugin itself so
// both ends agree. SIM.yaml has an io.sim block of the same name whose `signals` are the TPDO
// entries and whose `command` the RPDO entries, in order, with the same names and units. Per
// SYNC the module advances the plant by one period under the outputs latched so far, samples
// it and answers with its TPDOs: the timing of io.sim in a pipeline.
//
// --fault injects one of the module faults of the tests (heartbeat_lost, malformed_pdo,
// bus_off, emergency, silent) after N SYNCs (SIGSTOP makes the process really silent).
// --sync-watchdog-ms (default 100, 0 off): operational and no SYNC for that long, the module
// drives its outputs to the RPDO entries' safe values on its own and goes pre-operational, as
// a module configured for it does when its master dies without a word (SIGKILL, power).
// Stops on SIGINT/SIGTERM and prints what it served and the outputs it holds. Exit codes:
// 0 stopped, 2 configuration error.
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "daq_mapping.hpp"
#include "emulator.hpp"
#include "lode/sdk/testing/block_host.hpp"
#include "pipeline_file.hpp"
#include "sim_plant.hpp"

namespace {

constexpr int kExitConfig = 2;
constexpr const char* kUsage =
    "usage: lode-can-emu BOARD.yaml --sim SIM.yaml [--block NAME] [--interface IF]\n"
    "                    [--fault heartbeat_lost|malformed_pdo|bus_off|emergency|silent --fault-after-syncs N]\n"
    "                    [--heartbeat-ms MS] [--sync-watchdog-ms MS]\n";
constexpr const char* kHelp =
    "\n"
    "Plays the CANopen DAQ module of an io.socketcan_daq block on a CAN interface, its analog\n"
    "inputs (TPDOs) driven by the io.sim block of SIM.yaml (plant, sensors, noise) and its analog\n"
    "outputs (RPDOs) driving that plant: a closed loop over CAN frames without the module. Start\n"
    "it before `lode run BOARD.yaml`; stop it with Ctrl-C (it prints what it served).\n"
    "\n"
    "  BOARD.yaml            the pipeline with the io.socketcan_daq block (node id, PDOs, interface)\n"
    "  --sim SIM.yaml        a pipeline with an io.sim block of the same name: its signals are the\n"
    "                        TPDO entries, its command the RPDO entries, in order\n"
    "  --block NAME          which block of both files (default: the first io.socketcan_daq one)\n"
    "  --interface IF        the CAN interface (default: the block's, e.g. vcan0)\n"
    "  --fault KIND          a module fault after --fault-after-syncs N SYNCs: heartbeat_lost,\n"
    "                        malformed_pdo, bus_off, emergency or silent\n"
    "  --heartbeat-ms MS     heartbeat period (default 20)\n"
    "  --sync-watchdog-ms MS no SYNC for that long: outputs to their safe values, pre-operational\n"
    "                        (default 100, 0 off), as a module whose master died does\n"
    "\n"
    "exit codes: 0 stopped, 2 configuration error. See docs/hardware.md.\n";
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

namespace co = lode::hal::canopen;
using lode::can_daq_emu::DaqNode;

struct ModulePdos {
  std::vector<co::PdoMapping> mappings;
  std::vector<lode::plugins::can_daq::Channel> channels;  // every entry, in order
};

/// The PDOs as the io.socketcan_daq block itself parsed them (its describe()).
ModulePdos pdos_of(const lode::Json& list) {
  ModulePdos out;
  for (const auto& p : list.elements()) {
    co::PdoMapping m;
    m.pdo = static_cast<int>(p.find("pdo")->as_number());
    for (const auto& e : p.find("entries")->elements()) {
      co::PdoEntry entry;
      entry.name = e.find("name")->as_string();
      entry.bits = static_cast<int>(e.find("bits")->as_number());
      entry.is_signed = e.find("signed")->as_bool();
      lode::plugins::can_daq::Channel c;
      c.name = entry.name;
      c.unit = e.find("unit")->as_string();
      c.scale = e.find("scale")->as_number();
      c.offset = e.find("offset")->as_number();
      if (const lode::Json* safe = e.find("safe_value")) c.safe_value = safe->as_number();
      m.entries.push_back(entry);
      out.channels.push_back(c);
    }
    out.mappings.push_back(m);
  }
  return out;
}

const std::map<std::string, DaqNode::Fault> kFaults = {
    {"silent", DaqNode::Fault::silent},         {"heartbeat_lost", DaqNode::Fault::heartbeat_lost},
    {"malformed_pdo", DaqNode::Fault::malformed_pdo}, {"bus_off", DaqNode::Fault::bus_off},
    {"emergency", DaqNode::Fault::emergency}};

}  // namespace

int main(int argc, char** argv) {
  std::string board_file, sim_file, block, interface, fault_name;
  long long fault_after = -1;
  int heartbeat_ms = 20;
  int watchdog_ms = 100;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--sim" && has_value) sim_file = argv[++i];
    else if (a == "--block" && has_value) block = argv[++i];
    else if (a == "--interface" && has_value) interface = argv[++i];
    else if (a == "--fault" && has_value) fault_name = argv[++i];
    else if (a == "--fault-after-syncs" && has_value) fault_after = std::atoll(argv[++i]);
    else if (a == "--heartbeat-ms" && has_value) heartbeat_ms = std::atoi(argv[++i]);
    else if (a == "--sync-watchdog-ms" && has_value) watchdog_ms = std::atoi(argv[++i]);
    else if (a == "-h" || a == "--help") {
      std::printf("%s%s", kUsage, kHelp);
      return 0;
    } else if (board_file.empty() && a[0] != '-') board_file = a;
    else {
      std::fprintf(stderr, "lode-can-emu: unknown argument '%s'\n%s", a.c_str(), kUsage);
      return kExitConfig;
    }
  }
  if (board_file.empty() || sim_file.empty()) {
    std::fprintf(stderr, "%s", kUsage);
    return kExitConfig;
  }
  if (!fault_name.empty() && (!kFaults.count(fault_name) || fault_after < 0)) {
    std::fprintf(stderr, "lode-can-emu: --fault needs one of heartbeat_lost, malformed_pdo, bus_off, emergency, "
                         "silent and --fault-after-syncs N\n");
    return kExitConfig;
  }
  if (heartbeat_ms <= 0) {
    std::fprintf(stderr, "lode-can-emu: --heartbeat-ms must be positive\n");
    return kExitConfig;
  }
  if (watchdog_ms < 0) {
    std::fprintf(stderr, "lode-can-emu: --sync-watchdog-ms must be >= 0 (0: off)\n");
    return kExitConfig;
  }
  auto found = lode::emu::find_block(board_file, "io.socketcan_daq", block);
  if (!found) {
    std::fprintf(stderr, "lode-can-emu: %s\n", found.error().c_str());
    return kExitConfig;
  }
  block = found->name;
  YAML::Node daq = found->node;
  // The module's side of the mapping, parsed and checked by the plugin (never activated here).
  lode::BlockHost backend("io.socketcan_daq", lode::emu::block_params_text(daq), 1000.0);
  if (daq["rpdo"]) {
    lode::Elements command;
    for (const auto& pdo : daq["rpdo"])
      for (const auto& e : pdo["entries"]) command.push_back({e["name"].as<std::string>(""), e["unit"].as<std::string>("V")});
    backend.feed("command", command);
  }
  if (auto st = backend.configure(); !st) {
    std::fprintf(stderr, "lode-can-emu: the io.socketcan_daq block '%s' of %s:\n%s\n", block.c_str(),
                 board_file.c_str(), backend.diagnostics().c_str());
    return kExitConfig;
  }
  const lode::Json described = backend.describe();
  if (interface.empty()) interface = described.find("interface")->as_string();
  const int node_id = static_cast<int>(described.find("node_id")->as_number());
  const ModulePdos tpdo = pdos_of(*described.find("tpdo"));
  const ModulePdos rpdo = pdos_of(*described.find("rpdo"));

  lode::Elements outputs;
  std::vector<std::string> input_names;
  for (const auto& c : rpdo.channels) outputs.push_back({c.name, c.unit});
  for (const auto& c : tpdo.channels) input_names.push_back(c.name);
  auto plant = lode::emu::SimPlant::open(sim_file, block, outputs, input_names);
  if (!plant) {
    std::fprintf(stderr, "lode-can-emu: %s\n", plant.error().c_str());
    return kExitConfig;
  }
  std::vector<double> command(rpdo.channels.size(), 0.0);
  std::uint64_t clipped_inputs = 0;
  auto frontend = [&](const std::vector<std::int64_t>& out_counts, std::vector<std::int64_t>& in_counts) {
    for (std::size_t i = 0; i < command.size(); ++i)
      command[i] = lode::plugins::can_daq::value_of(rpdo.channels[i], out_counts[i]);
    const auto values = (*plant)->sample_after(command);
    std::size_t k = 0;
    for (const auto& m : tpdo.mappings) {
      for (const auto& entry : m.entries) {
        bool clipped = false;
        in_counts[k] = lode::plugins::can_daq::count_of(entry, tpdo.channels[k], values[k], clipped);
        clipped_inputs += clipped ? 1 : 0;
        ++k;
      }
    }
  };
  // The node hears NMT, SYNC and its RPDOs; error frames always arrive and are ignored.
  std::vector<lode::hal::CanFilter> filters = {{co::kNmt, 0x7ff}, {co::kSync, 0x7ff}};
  for (const auto& m : rpdo.mappings) filters.push_back({co::rpdo_cob(m.pdo, node_id), 0x7ff});
  auto socket = lode::hal::CanSocket::open(interface, filters);
  if (!socket) {
    std::fprintf(stderr, "lode-can-emu: %s\n", socket.error().c_str());
    return kExitConfig;
  }
  DaqNode node(std::move(*socket), node_id, tpdo.mappings, rpdo.mappings, frontend,
               std::chrono::milliseconds(heartbeat_ms));
  if (watchdog_ms > 0) {
    // The module's own safe state: each RPDO entry's safe_value, as the block would send it.
    std::vector<std::int64_t> safe;
    for (std::size_t k = 0, first = 0; k < rpdo.mappings.size(); first += rpdo.mappings[k].entries.size(), ++k)
      for (std::size_t e = 0; e < rpdo.mappings[k].entries.size(); ++e) {
        bool clipped = false;
        const auto& c = rpdo.channels[first + e];
        safe.push_back(lode::plugins::can_daq::count_of(rpdo.mappings[k].entries[e], c, c.safe_value, clipped));
      }
    node.set_sync_watchdog(std::chrono::milliseconds(watchdog_ms), std::move(safe));
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::printf("lode-can-emu: serving node %d on %s (%zu TPDO entries, %zu RPDO entries), plant from io.sim '%s' of %s\n",
              node_id, interface.c_str(), tpdo.channels.size(), rpdo.channels.size(), block.c_str(), sim_file.c_str());
  std::fflush(stdout);
  node.start();
  bool fault_injected = false, synced = false;
  std::uint64_t trips_told = 0;
  while (!g_stop.load()) {
    if (node.watchdog_trips() > trips_told) {
      trips_told = node.watchdog_trips();
      std::printf("lode-can-emu: SYNC watchdog: no SYNC for %d ms while operational: outputs driven to their safe "
                  "values, pre-operational\n", watchdog_ms);
      std::fflush(stdout);
    }
    if (!synced && node.syncs() > 0) {
      synced = true;  // scripts wait for this line: the pipeline is running
      std::printf("lode-can-emu: first SYNC\n");
      std::fflush(stdout);
    }
    if (!fault_name.empty() && !fault_injected && node.syncs() >= static_cast<std::uint64_t>(fault_after)) {
      node.set_fault(kFaults.at(fault_name));
      fault_injected = true;
      std::printf("lode-can-emu: fault %s injected after SYNC %llu\n", fault_name.c_str(),
                  static_cast<unsigned long long>(node.syncs()));
      std::fflush(stdout);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(fault_injected || fault_name.empty() ? 10000 : 100));
  }
  node.set_fault(DaqNode::Fault::none);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // what was sent before the signal is taken
  node.stop();
  std::printf("lode-can-emu: stopped after %llu SYNC, %llu TPDO sent, %llu RPDO received, %llu plant faults, "
              "%llu inputs clipped\n",
              static_cast<unsigned long long>(node.syncs()), static_cast<unsigned long long>(node.tpdos_sent()),
              static_cast<unsigned long long>(node.rpdos_received()),
              static_cast<unsigned long long>((*plant)->faults()), static_cast<unsigned long long>(clipped_inputs));
  std::printf("lode-can-emu: outputs held:");
  const auto held = node.outputs();
  for (std::size_t i = 0; i < held.size(); ++i)
    std::printf(" %s=%lld (%.6g %s)", rpdo.channels[i].name.c_str(), static_cast<long long>(held[i]),
                lode::plugins::can_daq::value_of(rpdo.channels[i], held[i]), rpdo.channels[i].unit.c_str());
  std::printf("\n");
  return 0;
}
