#include "lode/hal/can_socket.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

namespace lode::hal {

CanSocket::~CanSocket() {
  if (fd_ >= 0) close(fd_);
}

CanSocket::CanSocket(CanSocket&& other) noexcept : fd_(std::exchange(other.fd_, -1)), name_(std::move(other.name_)) {}

CanSocket& CanSocket::operator=(CanSocket&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    name_ = std::move(other.name_);
  }
  return *this;
}

int CanSocket::release() noexcept { return std::exchange(fd_, -1); }

Expected<CanSocket> CanSocket::open(const std::string& interface, const std::vector<CanFilter>& filters) {
  CanSocket s;
  s.name_ = interface;
  if (interface.rfind("fd:", 0) == 0) {
    char* end = nullptr;
    const long fd = std::strtol(interface.c_str() + 3, &end, 10);
    if (end == interface.c_str() + 3 || *end != '\0' || fd < 0 || fcntl(static_cast<int>(fd), F_GETFD) < 0)
      return Status::error("CAN interface '" + interface + "': not an open descriptor");
    s.fd_ = static_cast<int>(fd);
  } else {
    if (interface.empty() || interface.size() >= IFNAMSIZ)
      return Status::error("CAN interface name '" + interface + "' is empty or too long");
    const unsigned index = if_nametoindex(interface.c_str());
    if (index == 0)
      return Status::error("CAN interface '" + interface + "' does not exist (ip link add dev " + interface +
                           " type vcan; ip link set " + interface + " up)");
    s.fd_ = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (s.fd_ < 0) return Status::error("CAN interface '" + interface + "': socket(PF_CAN): " + std::strerror(errno));
    if (!filters.empty()) {
      std::vector<can_filter> kernel;
      for (const auto& f : filters) kernel.push_back({f.id, f.mask});
      if (setsockopt(s.fd_, SOL_CAN_RAW, CAN_RAW_FILTER, kernel.data(),
                     static_cast<socklen_t>(kernel.size() * sizeof(can_filter))) != 0)
        return Status::error("CAN interface '" + interface + "': receive filters: " + std::strerror(errno));
    }
    const can_err_mask_t errors = CAN_ERR_MASK;  // every error class: bus-off, passive, no ACK...
    if (setsockopt(s.fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) != 0)
      return Status::error("CAN interface '" + interface + "': error frames: " + std::strerror(errno));
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(index);
    if (bind(s.fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      return Status::error("CAN interface '" + interface + "': bind: " + std::strerror(errno));
  }
  // Receive timestamps: the bus-side arrival time, apart from how late the reader ran. Also on
  // an adopted descriptor (AF_UNIX datagrams are timestamped the same way); harmless if refused.
  const int on = 1;
  (void)setsockopt(s.fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  const int flags = fcntl(s.fd_, F_GETFL);
  if (flags < 0 || fcntl(s.fd_, F_SETFL, flags | O_NONBLOCK) != 0)
    return Status::error("CAN interface '" + interface + "': non-blocking mode: " + std::strerror(errno));
  return s;
}

Expected<std::pair<CanSocket, CanSocket>> CanSocket::pair() {
  int fds[2];
  if (socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC | SOCK_NONBLOCK, 0, fds) != 0)
    return Status::error(std::string("CAN socket pair: ") + std::strerror(errno));
  std::pair<CanSocket, CanSocket> p;
  p.first.fd_ = fds[0];
  p.first.name_ = "fd:" + std::to_string(fds[0]);
  p.second.fd_ = fds[1];
  p.second.name_ = "fd:" + std::to_string(fds[1]);
  const int on = 1;
  for (const int fd : fds) (void)setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  return p;
}

bool CanSocket::send(const CanFrame& frame) noexcept {
  std::uint8_t bytes[kCanFrameBytes];
  encode_can_frame(frame, bytes);
  return ::send(fd_, bytes, sizeof bytes, MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(sizeof bytes);
}

CanSocket::Receive CanSocket::receive(CanFrame& frame, const char*& why) noexcept {
  std::uint8_t bytes[kCanFrameBytes + 64];  // room to see an oversized datagram as such
  alignas(cmsghdr) std::uint8_t control[CMSG_SPACE(sizeof(timespec))];
  iovec iov{bytes, sizeof bytes};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return Receive::none;
    why = "CAN socket receive failed";
    return Receive::failed;
  }
  if (n == 0) {
    why = "CAN socket closed by the other end";
    return Receive::failed;
  }
  why = decode_can_frame(bytes, static_cast<std::size_t>(n), frame);
  frame.timestamp_ns = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      frame.timestamp_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    }
  }
  return why ? Receive::malformed : Receive::frame;
}

bool CanSocket::wait_readable(std::int64_t timeout_ns) noexcept {
  pollfd p{fd_, POLLIN, 0};
  timespec ts{};
  if (timeout_ns > 0) {
    ts.tv_sec = timeout_ns / 1'000'000'000;
    ts.tv_nsec = timeout_ns % 1'000'000'000;
  }
  return ppoll(&p, 1, &ts, nullptr) > 0;
}

}  // namespace lode::hal
