// A CAN socket for the backends (hal/): SocketCAN CAN_RAW bound to an interface
// (vcan0, can0) with receive filters, error frames and kernel receive timestamps enabled,
// non-blocking; or, for tests and emulators, one end of a connected socket pair carrying
// `struct can_frame` datagrams (timestamped too).
//
//   auto s = CanSocket::open("vcan0", {{0x185, 0x7ff}});   // id, mask
//   s->send(sync);                                           // RT path: no allocation
//   CanFrame f; const char* why;
//   while (s->receive(f, why) == CanSocket::Receive::frame) ...
//
// open() and pair() may allocate and fail with a message; send/receive/wait are noexcept.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "lode/hal/can_frame.hpp"
#include "lode/sdk/status.hpp"

namespace lode::hal {

struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0x7ff;
};

class CanSocket {
 public:
  CanSocket() = default;
  ~CanSocket();
  CanSocket(CanSocket&& other) noexcept;
  CanSocket& operator=(CanSocket&& other) noexcept;
  CanSocket(const CanSocket&) = delete;
  CanSocket& operator=(const CanSocket&) = delete;

  /// "vcan0", "can0": CAN_RAW on that interface (filters empty = every frame; error frames
  /// are always delivered). "fd:N": adopt descriptor N, a datagram socket carrying
  /// struct can_frame (one end of pair(), handed over by a test or an emulator).
  static Expected<CanSocket> open(const std::string& interface, const std::vector<CanFilter>& filters = {});
  /// A connected pair of datagram sockets carrying struct can_frame: a bus of two nodes.
  static Expected<std::pair<CanSocket, CanSocket>> pair();

  /// False when the frame could not be queued (the bus is down, the queue is full).
  bool send(const CanFrame& frame) noexcept;
  enum class Receive { frame, none, malformed, failed };
  /// One frame if one is waiting, with the kernel's receive time in frame.timestamp_ns (when
  /// it took the frame off the bus, not when we read it). `malformed`: bytes that are no CAN
  /// frame (why says how).
  Receive receive(CanFrame& frame, const char*& why) noexcept;
  /// Wait until a frame is waiting or `timeout_ns` passed; false on timeout.
  bool wait_readable(std::int64_t timeout_ns) noexcept;

  [[nodiscard]] int fd() const noexcept { return fd_; }
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  /// Give up ownership of the descriptor (it stays open); for handing one end to another owner.
  int release() noexcept;

 private:
  int fd_ = -1;
  std::string name_;
};

}  // namespace lode::hal
