// A CANopen DAQ module on a CAN socket: answers NMT, sends its heartbeat, sends its
// TPDOs after every SYNC while operational, takes its RPDOs. What its inputs read comes from
// a front end (in tests a loopback of its outputs; in an emulator process a simulated plant).
//
// Faults for tests: `silent` (frozen: reads nothing, answers nothing, no heartbeat; what was
// sent meanwhile is handled when it thaws), `heartbeat_lost` (PDOs go on,
// heartbeats stop), `malformed_pdo` (TPDOs one byte short), `bus_off` (one error frame saying
// bus-off: only meaningful on a socket pair, where this node plays the local controller too),
// `emergency` (one EMCY with error code 0x2310, output current too high).
//
// SYNC watchdog (as a module's communication-cycle supervision, CiA 301 0x1006 with the error
// behaviour of 0x1029 and the DS401 output error values 0x6443/0x6444): operational and no
// SYNC for the set time, the module drives its outputs to the safe counts on its own and
// drops to pre-operational. This is what covers a master that can no longer drive them safe
// (killed with SIGKILL, powered off, cable pulled).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <thread>
#include <vector>

#include "lode/hal/can_socket.hpp"
#include "lode/hal/canopen.hpp"
#include "polling_thread.hpp"

namespace lode::can_daq_emu {

class DaqNode {
 public:
  enum class Fault : int { none, silent, heartbeat_lost, malformed_pdo, bus_off, emergency };
  /// outputs: every RPDO entry's count, in order; inputs: every TPDO entry's count to send.
  using Frontend = std::function<void(const std::vector<std::int64_t>& outputs, std::vector<std::int64_t>& inputs)>;

  DaqNode(hal::CanSocket socket, int node, std::vector<hal::canopen::PdoMapping> tpdo,
          std::vector<hal::canopen::PdoMapping> rpdo, Frontend frontend,
          std::chrono::milliseconds heartbeat_period = std::chrono::milliseconds(20));
  ~DaqNode();
  DaqNode(const DaqNode&) = delete;
  DaqNode& operator=(const DaqNode&) = delete;

  /// Handle what arrived and send a heartbeat when due. True when it did something.
  bool poll();
  void start();
  void stop();

  void set_fault(Fault fault) { fault_.store(static_cast<int>(fault)); }
  /// Arm the SYNC watchdog (before start()): `safe` has one count per RPDO entry. 0 disarms.
  void set_sync_watchdog(std::chrono::microseconds timeout, std::vector<std::int64_t> safe);
  /// Times the watchdog drove the outputs safe.
  [[nodiscard]] std::uint64_t watchdog_trips() const { return watchdog_trips_.load(); }
  [[nodiscard]] std::uint64_t syncs() const { return syncs_.load(); }
  [[nodiscard]] std::uint64_t tpdos_sent() const { return tpdos_sent_.load(); }
  [[nodiscard]] std::uint64_t rpdos_received() const { return rpdos_received_.load(); }
  /// The last RPDO entry counts received (what the outputs drive), from any thread.
  [[nodiscard]] std::vector<std::int64_t> outputs() const;
  [[nodiscard]] hal::canopen::NmtState state() const { return static_cast<hal::canopen::NmtState>(state_.load()); }

 private:
  void send_heartbeat();
  /// Between polls that found nothing: until a frame arrives or the next heartbeat or
  /// watchdog check is due (a frozen node just sleeps).
  void wait_for_work();

  hal::CanSocket socket_;
  int node_;
  std::vector<hal::canopen::PdoMapping> tpdo_, rpdo_;
  Frontend frontend_;
  std::chrono::milliseconds heartbeat_period_;
  std::chrono::steady_clock::time_point next_heartbeat_{};
  std::vector<std::int64_t> outputs_, inputs_;
  std::vector<std::atomic<std::int64_t>> outputs_published_;
  std::atomic<int> state_{static_cast<int>(hal::canopen::NmtState::pre_operational)};
  std::atomic<int> fault_{0};
  int fault_sent_ = 0;  // the one-shot faults already sent
  std::chrono::microseconds sync_watchdog_{0};
  std::vector<std::int64_t> safe_outputs_;
  std::chrono::steady_clock::time_point last_sync_{};
  std::atomic<std::uint64_t> watchdog_trips_{0};
  std::atomic<std::uint64_t> syncs_{0}, tpdos_sent_{0}, rpdos_received_{0};
  plugins::boards::PollingThread poller_;  // last: stopped before the members it polls go
};

}  // namespace lode::can_daq_emu
