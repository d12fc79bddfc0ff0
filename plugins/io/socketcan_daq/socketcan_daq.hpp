// io.socketcan_daq: a CANopen-style analog DAQ module over SocketCAN.
//
// @system
// name: io.socketcan_daq
// input_ports:
//   command: [every rpdo entry, in its unit]     # write phase: the module's analog outputs
// output_ports:                                  # read phase
//   signals: [every tpdo entry, in its unit]     # the module's analog inputs, scaled
//   counts:  [every tpdo entry, 1]               # the raw integers of the PDOs
// @endsystem
//
// activate(): NMT start to the node, then wait (up to heartbeat_timeout_ms) for its heartbeat
// saying operational. Read phase: SYNC, then every configured TPDO of the node within
// pdo_timeout_us; heartbeats, EMCY and error frames seen meanwhile are handled. Write phase:
// the RPDOs from `command`. Faults (fixed reasons): a TPDO missing at the timeout, a PDO whose
// length is not its mapping's, the heartbeat silent for heartbeat_timeout_ms or reporting a
// state other than operational, an EMCY with an error code, a bus-off / error-passive / no-ACK
// error frame, a send the kernel refused. drive_safe() sends the RPDOs with every entry's safe
// value; deactivate() does that and then NMT pre-operational.
//
// Threads: configure/activate/deactivate on the loader thread; step/write/drive_safe on the RT
// thread: no allocation or lock; the only system calls are the socket's send/recv/ppoll and the
// clock.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "acquisition_board.hpp"
#include "daq_mapping.hpp"
#include "lode/sdk/histogram.hpp"
#include "lode/hal/can_socket.hpp"

namespace lode::plugins {

class SocketCanDaq final : public boards::AcquisitionBoard {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  StepStatus write(const Tick& tick) noexcept override;
  void drive_safe() noexcept override;
  void deactivate() noexcept override;
  void describe(Json& out) const override;

  /// Frames this block received and sent since activate(), and SYNC cycles whose TPDOs all came.
  [[nodiscard]] std::uint64_t frames_received() const noexcept { return received_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t complete_cycles() const noexcept { return complete_.load(std::memory_order_relaxed); }
  /// SYNC sent -> the cycle's last TPDO received by the kernel, per complete cycle.
  [[nodiscard]] const Histogram& sync_to_tpdo() const noexcept { return sync_to_tpdo_; }
  [[nodiscard]] std::uint16_t last_emergency_code() const noexcept { return emcy_code_.load(std::memory_order_relaxed); }

 private:
  /// Handle one frame that is not an expected TPDO; a reason when it is a fault.
  const char* supervise(const hal::CanFrame& frame, std::int64_t now_ns) noexcept;
  void send_rpdos(bool safe) noexcept;

  std::string interface_;
  int node_ = 1;
  std::int64_t heartbeat_timeout_ns_ = 0;
  std::int64_t pdo_timeout_ns_ = 0;
  std::vector<can_daq::Pdo> tpdo_, rpdo_;
  std::size_t output_count_ = 0;

  hal::CanSocket socket_;
  std::int64_t last_heartbeat_ns_ = 0;
  std::vector<std::uint8_t> tpdo_seen_;      // per TPDO, this cycle
  std::vector<std::int64_t> raw_;            // scratch: one PDO's counts
  std::atomic<std::uint64_t> received_{0}, complete_{0};
  /// SYNC sent to the cycle's last TPDO taken off the bus (kernel receive timestamp): the
  /// module's and the bus's share of the read phase, apart from this thread's scheduling.
  Histogram sync_to_tpdo_;
  std::atomic<std::uint16_t> emcy_code_{0};
};

}  // namespace lode::plugins
