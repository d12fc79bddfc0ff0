// A CANopen DAQ module on a CAN socket (issue 6): answers NMT, sends its heartbeat, sends its
// TPDOs after every SYNC while operational, takes its RPDOs. What its inputs read comes from
// a front end (in tests a loopback of its outputs; in an emulator process a simulated plant).
//
// Faults for tests: `silent` (frozen: reads nothing, answers nothing, no heartbeat; what was
// sent meanwhile is handled when it thaws), `heartbeat_lost` (PDOs go on,
// heartbeats stop), `malformed_pdo` (TPDOs one byte short), `bus_off` (one error frame saying
// bus-off: only meaningful on a socket pair, where this node plays the local controller too),
// `emergency` (one EMCY with error code 0x2310, output current too high).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <thread>
#include <vector>

#include "lode/hal/can_socket.hpp"
#include "lode/hal/canopen.hpp"

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
  [[nodiscard]] std::uint64_t syncs() const { return syncs_.load(); }
  [[nodiscard]] std::uint64_t tpdos_sent() const { return tpdos_sent_.load(); }
  [[nodiscard]] std::uint64_t rpdos_received() const { return rpdos_received_.load(); }
  /// The last RPDO entry counts received (what the outputs drive), from any thread.
  [[nodiscard]] std::vector<std::int64_t> outputs() const;
  [[nodiscard]] hal::canopen::NmtState state() const { return static_cast<hal::canopen::NmtState>(state_.load()); }

 private:
  void send_heartbeat();

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
  std::atomic<std::uint64_t> syncs_{0}, tpdos_sent_{0}, rpdos_received_{0};
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace lode::can_daq_emu
