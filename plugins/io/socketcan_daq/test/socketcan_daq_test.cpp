// io.socketcan_daq against the DAQ node emulator over a socket pair carrying struct can_frame
// (the same frames a CAN_RAW socket on vcan0 carries) or, with LODE_CAN_INTERFACE=vcan0 (the
// QEMU guest test, tests/qemu), over a real CAN interface: NMT start and the operational
// heartbeat, SYNC -> TPDO exchange with no lost frame, RPDOs latched by the node, and the
// hardware faults each detected with the outputs driven safe: the node silent, the heartbeat
// lost, bus-off, a malformed PDO length, an EMCY. Plus no allocation per cycle and located
// configuration errors.
#include "emulator.hpp"
#include "socketcan_daq.hpp"

#include <gtest/gtest.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "io_testing.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

using lode::StepStatus;
using lode::can_daq_emu::DaqNode;
using lode::plugins::boards::testing::refusal_of;
using lode::testing::BlockHarness;
namespace co = lode::hal::canopen;

const lode::Elements kCommand = {{"fx", "N"}, {"fy", "N"}};

/// Node 5: TPDO1 two 16-bit inputs (a1, b1, 1 mV per count), TPDO2 one 32-bit input (c1);
/// RPDO1 two 16-bit outputs (fx, fy; 10 mN per count; safe 0 N and 2 N).
std::string params(const std::string& interface, double heartbeat_ms = 200.0, double pdo_us = 20000.0) {
  return "interface: " + interface + "\nnode_id: 5\nheartbeat_timeout_ms: " + std::to_string(heartbeat_ms) +
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

/// A real CAN interface to run on (LODE_CAN_INTERFACE, set by the QEMU guest test), or null:
/// then the block and the node share a socket pair.
const char* real_interface() {
  const char* name = std::getenv("LODE_CAN_INTERFACE");
  return name != nullptr && *name != '\0' ? name : nullptr;
}

/// The SYNC -> TPDO timeout of the exchange tests. On a real interface these run in an emulated
/// guest (tests/qemu) on a shared host, whose vCPUs can be off the host CPU for tens of ms:
/// a generous timeout tells a late frame (fine here) from a lost one (a fault, and a gap in the
/// SYNC counter). The fault tests keep their tight timeouts and measure detection.
double exchange_pdo_timeout_us() { return real_interface() != nullptr ? 500000.0 : 20000.0; }

/// Loopback wiring of the module: a1 reads what fx outputs, b1 what fy outputs, c1 counts syncs.
struct Rig {
  explicit Rig(double heartbeat_ms = 200.0, double pdo_us = exchange_pdo_timeout_us(),
               std::chrono::milliseconds sync_watchdog = std::chrono::milliseconds(0)) {
    lode::hal::CanSocket node_end;
    std::string interface;
    if (const char* name = real_interface()) {
      // The node hears what a module hears: NMT, SYNC, its RPDO (error frames always).
      auto s = lode::hal::CanSocket::open(name, {{co::kNmt, 0x7ff}, {co::kSync, 0x7ff}, {co::rpdo_cob(1, 5), 0x7ff}});
      if (!s) {
        ADD_FAILURE() << s.error();
        return;
      }
      node_end = std::move(*s);
      interface = name;
    } else {
      auto pair = lode::hal::CanSocket::pair();
      if (!pair) {
        ADD_FAILURE() << pair.error();
        return;
      }
      node_end = std::move(pair->second);
      interface = "fd:" + std::to_string(pair->first.release());
    }
    node = std::make_unique<DaqNode>(std::move(node_end), 5, node_tpdo(), node_rpdo(),
                                     [this](const std::vector<std::int64_t>& out, std::vector<std::int64_t>& in) {
                                       in[0] = out[0];
                                       in[1] = out[1];
                                       in[2] = ++conversions;
                                     });
    node->set_sync_watchdog(sync_watchdog, {0, 200});  // the block's safe values, in counts
    node->start();
    h = std::make_unique<BlockHarness>("io.socketcan_daq", params(interface, heartbeat_ms, pdo_us), 1000.0);
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
      h->board().drive_safe();  // what the pipeline does on a fault
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

  std::int64_t conversions = 0;
  std::unique_ptr<DaqNode> node;
  std::unique_ptr<BlockHarness> h;
  bool ok = false;
};

/// What both ends counted, for a failure message: lost or late?
std::string counters(Rig& rig) {
  return "node: " + std::to_string(rig.node->syncs()) + " SYNC, " + std::to_string(rig.node->tpdos_sent()) +
         " TPDO sent; block: " + std::to_string(rig.daq().complete_cycles()) + " complete cycles, " +
         std::to_string(rig.daq().frames_received()) + " frames received";
}

TEST(SocketCanDaq, StartsTheNodeAndExchangesPdosEveryCycleWithNoLostFrame) {
  Rig rig;
  ASSERT_TRUE(rig.ok);
  EXPECT_EQ(rig.node->state(), co::NmtState::operational);
  EXPECT_EQ(rig.node->outputs(), (std::vector<std::int64_t>{0, 200}));  // safe values before the first cycle
  const int cycles = 2000;
  for (int k = 0; k < cycles; ++k) {
    const double fx = 3.0 * std::sin(0.01 * k);
    ASSERT_EQ(rig.cycle(fx, -1.5), "") << "cycle " << k << "; " << counters(rig);
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
  // Every complete cycle timed from SYNC to its last TPDO by the kernel's receive timestamps.
  EXPECT_EQ(rig.daq().sync_to_tpdo().count(), static_cast<std::uint64_t>(cycles));
  EXPECT_GT(rig.daq().sync_to_tpdo().min(), 0) << "a TPDO cannot arrive before its SYNC was sent";
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

// PDO exchange at 1 kHz for 10 s on a real CAN socket with no lost frame. Paced by
// absolute 1 ms deadlines (CLOCK_MONOTONIC); a late cycle starts at once and is counted. Lost,
// repeated or reordered frames show in the TPDO2 SYNC counter (must advance by exactly one per
// cycle), in a1 (must read the fx counts of the previous cycle's RPDO) and in the counts of
// both ends. The timeout is exchange_pdo_timeout_us(), so a late answer (a guest off the host
// CPU) is told apart from a lost one; the SYNC -> last TPDO times are printed.
TEST(SocketCanDaqOnInterface, ThousandHertzForTenSecondsWithNoLostFrame) {
  if (real_interface() == nullptr) GTEST_SKIP() << "LODE_CAN_INTERFACE not set (the QEMU guest test sets vcan0)";
  Rig rig(100.0);
  ASSERT_TRUE(rig.ok);
  constexpr int kCycles = 10000;
  std::vector<double> answer_us;
  answer_us.reserve(kCycles);
  int late_cycles = 0;
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  const auto t_start = std::chrono::steady_clock::now();
  for (int k = 0; k < kCycles; ++k) {
    next.tv_nsec += 1'000'000;
    if (next.tv_nsec >= 1'000'000'000) {
      next.tv_nsec -= 1'000'000'000;
      ++next.tv_sec;
    }
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    if (now.tv_sec > next.tv_sec || (now.tv_sec == next.tv_sec && now.tv_nsec > next.tv_nsec)) {
      ++late_cycles;
      next = now;
    } else {
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
    }
    const double fx = 3.0 * std::sin(0.01 * k);
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(rig.cycle(fx, -1.5), "") << "cycle " << k << "; " << counters(rig);
    answer_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    ASSERT_EQ(rig.h->output("counts")[2], static_cast<double>(k + 1)) << "TPDO2's SYNC count: a frame lost at cycle " << k;
    if (k > 0) {
      const double expected_counts = std::floor(3.0 * std::sin(0.01 * (k - 1)) / 1e-2 + 0.5);
      ASSERT_EQ(rig.h->output("counts")[0], expected_counts) << "the RPDO of cycle " << k - 1 << " not latched";
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  EXPECT_EQ(rig.daq().complete_cycles(), static_cast<std::uint64_t>(kCycles));
  for (int i = 0; i < 200 && rig.node->rpdos_received() < static_cast<std::uint64_t>(kCycles + 1); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(rig.node->syncs(), static_cast<std::uint64_t>(kCycles));
  EXPECT_EQ(rig.node->tpdos_sent(), static_cast<std::uint64_t>(2 * kCycles));
  // One safe RPDO at activation, then one per cycle.
  EXPECT_EQ(rig.node->rpdos_received(), static_cast<std::uint64_t>(kCycles + 1));
  std::sort(answer_us.begin(), answer_us.end());
  std::printf("%s: %d cycles in %.2f s (%d started late): %llu SYNC, %llu TPDO, %llu RPDO, %llu frames received by "
              "the block, none lost; read phase (SYNC -> both TPDOs) p50 %.0f us, p99 %.0f us, max %.0f us\n",
              real_interface(), kCycles, seconds, late_cycles, static_cast<unsigned long long>(rig.node->syncs()),
              static_cast<unsigned long long>(rig.node->tpdos_sent()),
              static_cast<unsigned long long>(rig.node->rpdos_received()),
              static_cast<unsigned long long>(rig.daq().frames_received()), answer_us[kCycles / 2],
              answer_us[kCycles * 99 / 100], answer_us.back());
  const lode::Histogram& bus = rig.daq().sync_to_tpdo();
  EXPECT_EQ(bus.count(), static_cast<std::uint64_t>(kCycles));
  std::printf("%s: SYNC sent -> last TPDO received by the kernel (receive timestamps): p50 %.0f us, p99 %.0f us, "
              "max %.0f us\n",
              real_interface(), bus.percentile(0.5) * 1e-3, bus.percentile(0.99) * 1e-3, static_cast<double>(bus.max()) * 1e-3);
}

// The module's side of safe outputs: a master that dies without a word (SIGKILL, power) sends
// no safe RPDO, so the module's SYNC watchdog drives its outputs safe and leaves operational;
// a master still alive then sees that in the heartbeat.
TEST(SocketCanDaqEmulator, SyncWatchdogDrivesTheOutputsSafeWhenTheMasterGoesQuiet) {
  Rig rig(200.0, exchange_pdo_timeout_us(), std::chrono::milliseconds(50));
  ASSERT_TRUE(rig.ok);
  // Taken before each cycle's SYNC goes out, so before the module receives the last one: a
  // thread held off the CPU after that cycle can only lengthen the time measured below, never
  // make a watchdog that waited its 50 ms look early (a time taken after the cycle could).
  auto quiet_from = std::chrono::steady_clock::now();
  for (int k = 0; k < 20; ++k) {
    quiet_from = std::chrono::steady_clock::now();
    ASSERT_EQ(rig.cycle(3.0, -1.5), "") << "cycle " << k;
  }
  for (int i = 0; i < 200 && rig.node->outputs() != std::vector<std::int64_t>{300, -150}; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_EQ(rig.node->outputs(), (std::vector<std::int64_t>{300, -150}));
  for (int i = 0; i < 1000 && rig.node->watchdog_trips() == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - quiet_from).count();
  ASSERT_EQ(rig.node->watchdog_trips(), 1u) << "no trip within 1 s of the last SYNC";
  EXPECT_GE(ms, 45.0) << "tripped before the 50 ms watchdog time";
  EXPECT_EQ(rig.node->outputs(), (std::vector<std::int64_t>{0, 200}));
  EXPECT_EQ(rig.node->state(), co::NmtState::pre_operational);
  std::printf("SYNC watchdog 50 ms: outputs safe %.1f ms after the last SYNC\n", ms);
  EXPECT_EQ(rig.cycle(1.0, 1.0), "the node left the operational state (heartbeat)");
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
  EXPECT_LT(ms, 20.0 + 200.0);  // the timeout plus a loose margin for a shared machine
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, ALostHeartbeatIsDetectedWithinTheHeartbeatTimeout) {
  Rig rig(100.0);
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

/// Faults that arrive as a frame (not as a silence): injected after 20 good cycles, reported
/// with `reason` within two cycles (the node acts on its own thread between them), outputs safe.
void expect_frame_fault(Rig& rig, DaqNode::Fault fault, const std::string& reason) {
  ASSERT_TRUE(rig.ok);
  ASSERT_EQ(rig.until_fault(20).first, "");
  rig.node->set_fault(fault);
  EXPECT_EQ(rig.until_fault(2).first, reason);
  rig.expect_outputs_safe();
}

TEST(SocketCanDaqFaults, BusOffIsAFault) {
  Rig rig;
  expect_frame_fault(rig, DaqNode::Fault::bus_off, "CAN bus-off: the controller left the bus");
}

TEST(SocketCanDaqFaults, AMalformedPdoLengthIsAFault) {
  Rig rig;
  expect_frame_fault(rig, DaqNode::Fault::malformed_pdo, "PDO length does not match its mapping");
}

TEST(SocketCanDaqFaults, AnEmergencyIsAFaultWithItsCode) {
  Rig rig;
  expect_frame_fault(rig, DaqNode::Fault::emergency, "EMCY from the node (error code in describe())");
  EXPECT_EQ(rig.daq().last_emergency_code(), 0x2310);
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
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 300; ++k) ASSERT_EQ(rig.cycle(0.01 * k, 0.0), "");
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

TEST(SocketCanDaq, ANodeThatNeverStartsIsRefusedAtActivation) {
  auto pair = lode::hal::CanSocket::pair();
  ASSERT_TRUE(pair) << pair.error();
  // Nobody on the other end.
  BlockHarness h("io.socketcan_daq", params("fd:" + std::to_string(pair->first.release()), 50.0), 1000.0);
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
    const std::string d = refusal_of("io.socketcan_daq", c.params, 1000.0, {{"fx", "N"}});
    EXPECT_NE(d.find(c.expect), std::string::npos) << d;
  }
}

}  // namespace
