// io.socketcan_daq against the DAQ node emulator over a socket pair carrying struct can_frame
// (the same frames a CAN_RAW socket on vcan0 carries): NMT start and the operational
// heartbeat, SYNC -> TPDO exchange with no lost frame, RPDOs latched by the node, and the
// faults of issue 6 each detected with the outputs driven safe: the node silent, the heartbeat
// lost, bus-off, a malformed PDO length, an EMCY. Plus no allocation per cycle and located
// configuration errors.
#include "emulator.hpp"
#include "socketcan_daq.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "lode/testing/allocation_counter.hpp"
#include "lode/testing/harness.hpp"

namespace {

using lode::StepStatus;
using lode::can_daq_emu::DaqNode;
using lode::testing::BlockHarness;
namespace co = lode::hal::canopen;

const lode::Elements kCommand = {{"fx", "N"}, {"fy", "N"}};

/// Node 5: TPDO1 two 16-bit inputs (a1, b1, 1 mV per count), TPDO2 one 32-bit input (c1);
/// RPDO1 two 16-bit outputs (fx, fy; 10 mN per count; safe 0 N and 2 N).
std::string params(int fd, double heartbeat_ms = 200.0, double pdo_us = 20000.0) {
  return "interface: fd:" + std::to_string(fd) + "\nnode_id: 5\nheartbeat_timeout_ms: " + std::to_string(heartbeat_ms) +
         "\npdo_timeout_us: " + std::to_string(pdo_us) +
         "\ntpdo:\n"
         "  - {pdo: 1, entries: [{name: a1, bits: 16, scale: 1.0e-3, unit: V}, {name: b1, bits: 16, scale: 1.0e-3, unit: V}]}\n"
         "  - {pdo: 2, entries: [{name: c1, bits: 32, scale: 1.0e-6, unit: V}]}\n"
         "rpdo:\n"
         "  - {pdo: 1, entries: [{name: fx, bits: 16, scale: 1.0e-2, unit: N, safe_value: 0.0},"
         " {name: fy, bits: 16, scale: 1.0e-2, unit: N, safe_value: 2.0}]}\n";
}

std::vector<co::PdoMapping> node_tpdo() {
  return {{1, {{"a1", 16, true}, {"b1", 16, true}}}, {2, {{"c1", 32, true}}}};
}
std::vector<co::PdoMapping> node_rpdo() { return {{1, {{"fx", 16, true}, {"fy", 16, true}}}}; }

/// Loopback wiring of the module: a1 reads what fx outputs, b1 what fy outputs, c1 counts syncs.
struct Rig {
  explicit Rig(double heartbeat_ms = 200.0, double pdo_us = 20000.0) {
    auto pair = lode::hal::CanSocket::pair();
    if (!pair) {
      ADD_FAILURE() << pair.error();
      return;
    }
    host_fd = pair->first.fd();
    host_end = std::move(pair->first);
    node = std::make_unique<DaqNode>(std::move(pair->second), 5, node_tpdo(), node_rpdo(),
                                     [this](const std::vector<std::int64_t>& out, std::vector<std::int64_t>& in) {
                                       in[0] = out[0];
                                       in[1] = out[1];
                                       in[2] = ++conversions;
                                     });
    node->start();
    h = std::make_unique<BlockHarness>("io.socketcan_daq", params(host_end.release(), heartbeat_ms, pdo_us), 1000.0);
    h->feed("command", kCommand);
    if (!h->configure()) {
      ADD_FAILURE() << h->diagnostics();
      return;
    }
    if (auto st = h->activate(); !st) {
      ADD_FAILURE() << st.message();
      return;
    }
    ok = true;
  }
  lode::plugins::SocketCanDaq& daq() { return dynamic_cast<lode::plugins::SocketCanDaq&>(h->block()); }
  /// One cycle with these commands; the fault reason, or "".
  std::string cycle(double fx, double fy) {
    if (h->step() != StepStatus::ok) {
      h->block().drive_safe();  // what the pipeline does on a fault
      return h->block().fault_reason();
    }
    h->input("command")[0] = fx;
    h->input("command")[1] = fy;
    if (h->write() != StepStatus::ok) return h->block().fault_reason();
    return "";
  }
  /// Cycles until a fault; its reason and how long the failing cycle took.
  std::pair<std::string, double> until_fault(int max_cycles = 2000) {
    for (int k = 0; k < max_cycles; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      std::string why = cycle(1.0, 1.0);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (!why.empty()) return {why, ms};
      std::this_thread::sleep_for(std::chrono::milliseconds(1));  // a 1 kHz-ish loop
    }
    return {"", 0.0};
  }
  /// The node latched the safe values (fx 0 N, fy 2 N = 200 counts).
  void expect_outputs_safe() {
    node->set_fault(DaqNode::Fault::none);
    for (int i = 0; i < 500 && node->outputs() != std::vector<std::int64_t>{0, 200}; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_EQ(node->outputs(), (std::vector<std::int64_t>{0, 200}));
  }

  int host_fd = -1;
  lode::hal::CanSocket host_end;
  std::int64_t conversions = 0;
  std::unique_ptr<DaqNode> node;
  std::unique_ptr<BlockHarness> h;
  bool ok = false;
};

TEST(SocketCanDaq, StartsTheNodeAndExchangesPdosEveryCycleWithNoLostFrame) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  EXPECT_EQ(rig.node->state(), co::NmtState::operational);
  EXPECT_EQ(rig.node->outputs(), (std::vector<std::int64_t>{0, 200}));  // safe values before the first cycle
  const int cycles = 2000;
  for (int k = 0; k < cycles; ++k) {
    const double fx = 3.0 * std::sin(0.01 * k);
    ASSERT_EQ(rig.cycle(fx, -1.5), "") << "cycle " << k;
    if (k > 0) {
      // a1 reads the fx counts the node latched from the previous cycle's RPDO.
      const double expected_counts = std::floor(3.0 * std::sin(0.01 * (k - 1)) / 1e-2 + 0.5);
      ASSERT_EQ(rig.h->output("counts")[0], expected_counts) << "cycle " << k;
      ASSERT_NEAR(rig.h->output("signals")[0], expected_counts * 1e-3, 1e-12);
      ASSERT_EQ(rig.h->output("counts")[1], -150.0);
    }
    ASSERT_EQ(rig.h->output("counts")[2], static_cast<double>(k + 1)) << "TPDO2 carries the sync count";
  }
  EXPECT_EQ(rig.daq().complete_cycles(), static_cast<std::uint64_t>(cycles));
  // The node counts a TPDO after sending it: the block may have it before the count moves.
  for (int i = 0; i < 100 && rig.node->tpdos_sent() < static_cast<std::uint64_t>(2 * cycles); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(rig.node->syncs(), static_cast<std::uint64_t>(cycles));
  EXPECT_EQ(rig.node->tpdos_sent(), static_cast<std::uint64_t>(2 * cycles));
  std::printf("%d cycles: %llu SYNC, %llu TPDO sent, %llu RPDO latched, %llu frames received by the block\n", cycles,
              static_cast<unsigned long long>(rig.node->syncs()), static_cast<unsigned long long>(rig.node->tpdos_sent()),
              static_cast<unsigned long long>(rig.node->rpdos_received()),
              static_cast<unsigned long long>(rig.daq().frames_received()));
}

TEST(SocketCanDaqFaults, ASilentNodeIsAMissingTpdoWithinTheTimeout) {
  Rig rig(200.0, 20000.0);
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(DaqNode::Fault::silent);
  const auto [why, ms] = rig.until_fault();
  std::printf("silent node: '%s' after %.2f ms (pdo_timeout 20 ms)\n", why.c_str(), ms);
  EXPECT_EQ(why, "TPDO missing: not received within pdo_timeout_us of SYNC");
  EXPECT_GE(ms, 20.0);
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, ALostHeartbeatIsDetectedWithinTheHeartbeatTimeout) {
  Rig rig(100.0, 20000.0);
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(DaqNode::Fault::heartbeat_lost);
  const auto t0 = std::chrono::steady_clock::now();
  const auto [why, ms] = rig.until_fault();
  const double since = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("heartbeat lost: '%s' %.1f ms after the last heartbeat could have been sent (timeout 100 ms, period 20 ms)\n",
              why.c_str(), since);
  EXPECT_EQ(why, "heartbeat lost: none within heartbeat_timeout_ms");
  EXPECT_GE(since, 100.0 - 20.0);
  EXPECT_LT(since, 1000.0);  // loose: a shared machine
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, BusOffIsAFault) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(DaqNode::Fault::bus_off);
  EXPECT_EQ(rig.until_fault().first, "CAN bus-off: the controller left the bus");
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, AMalformedPdoLengthIsAFault) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(DaqNode::Fault::malformed_pdo);
  EXPECT_EQ(rig.until_fault().first, "PDO length does not match its mapping");
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, AnEmergencyIsAFaultWithItsCode) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(DaqNode::Fault::emergency);
  EXPECT_EQ(rig.until_fault().first, "EMCY from the node (error code in describe())");
  EXPECT_EQ(rig.daq().last_emergency_code(), 0x2310);
  rig.expect_outputs_safe();
}

TEST(SocketCanDaq, DeactivateDrivesTheOutputsSafeAndStopsTheNode) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(10).first, "");
  rig.h->deactivate();
  for (int i = 0; i < 500 && rig.node->state() != co::NmtState::pre_operational; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(rig.node->state(), co::NmtState::pre_operational);
  EXPECT_EQ(rig.node->outputs(), (std::vector<std::int64_t>{0, 200}));
}

TEST(SocketCanDaq, ACycleAllocatesNothing) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  if (!lode::testing::allocation_counting_available()) GTEST_SKIP() << "allocation counter not linked";
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 300; ++k) ASSERT_EQ(rig.cycle(0.01 * k, 0.0), "");
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

TEST(SocketCanDaq, ANodeThatNeverStartsIsRefusedAtActivation) {
  auto pair = lode::hal::CanSocket::pair();
  ASSERT_TRUE(pair) << pair.error();
  // Nobody on the other end.
  BlockHarness h("io.socketcan_daq", params(pair->first.release(), 50.0), 1000.0);
  h.feed("command", kCommand);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const auto st = h.activate();
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find("CAN node 5 on fd:"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("did not report operational within heartbeat_timeout_ms of NMT start (no heartbeat at all)"),
            std::string::npos)
      << st.message();
}

TEST(SocketCanDaq, ConfigurationErrorsNameTheField) {
  struct Case {
    std::string params, expect;
  };
  const std::string tpdo = "tpdo:\n  - {pdo: 1, entries: [{name: a1}]}\n";
  const std::vector<Case> cases = {
      {"interface: vcan0\nnode_id: 0\n" + tpdo, "a CANopen node id is 1 ... 127, got 0"},
      {"interface: vcan0\nnode_id: 5\ntpdo:\n  - {pdo: 1, entries: [{name: a1, bits: 12}]}\n",
       "entry 'a1': bits must be 8, 16 or 32, got 12"},
      {"interface: vcan0\nnode_id: 5\ntpdo:\n  - {pdo: 1, entries: [{name: a, bits: 32}, {name: b, bits: 32}, {name: c, bits: 8}]}\n",
       "maps 72 bits: a CAN frame carries at most 64"},
      {"interface: vcan0\nnode_id: 5\n" + tpdo + "rpdo:\n  - {pdo: 1, entries: [{name: fx, bits: 8, scale: 0.1, unit: N, safe_value: 20}]}\n",
       "entry 'fx': safe_value is outside what its 8-bit object carries"},
      {"interface: vcan0\nnode_id: 5\ntpdo:\n  - {pdo: 1, entries: [{name: a1}]}\n  - {pdo: 1, entries: [{name: b1}]}\n",
       "tpdo 1 is configured twice"},
      {"interface: vcan0\nnode_id: 5\ntpdo:\n  - {pdo: 1, entries: [{name: a1, scale: 0}]}\n", "scale"},
  };
  for (const auto& c : cases) {
    BlockHarness h("io.socketcan_daq", c.params, 1000.0);
    h.feed("command", {{"fx", "N"}});
    EXPECT_FALSE(h.configure()) << c.params;
    EXPECT_NE(h.diagnostics().find(c.expect), std::string::npos) << h.diagnostics();
  }
}

}  // namespace
