#include "lode/hal/can_frame.hpp"

#include <linux/can.h>
#include <linux/can/error.h>

#include <cstring>

namespace lode::hal {

static_assert(sizeof(struct can_frame) == kCanFrameBytes, "struct can_frame layout");

const char* decode_can_frame(const std::uint8_t* bytes, std::size_t size, CanFrame& out) noexcept {
  if (bytes == nullptr || size != kCanFrameBytes) return "not a classic CAN frame (a struct can_frame is 16 bytes)";
  std::uint32_t raw_id = 0;
  std::memcpy(&raw_id, bytes, sizeof raw_id);  // host byte order, as the kernel writes it
  const std::uint8_t length = bytes[4];
  if (length > 8) return "data length over 8 bytes";
  CanFrame f;
  f.extended = (raw_id & CAN_EFF_FLAG) != 0;
  f.remote = (raw_id & CAN_RTR_FLAG) != 0;
  f.error = (raw_id & CAN_ERR_FLAG) != 0;
  if (f.error) {
    f.id = raw_id & CAN_ERR_MASK;  // the error class bits
    if (length != CAN_ERR_DLC) return "error frame without its 8 data bytes";
  } else if (f.extended) {
    f.id = raw_id & CAN_EFF_MASK;
  } else {
    if ((raw_id & CAN_EFF_MASK) > CAN_SFF_MASK) return "standard frame with an identifier over 11 bits";
    f.id = raw_id & CAN_SFF_MASK;
  }
  f.length = length;
  if (!f.remote) std::memcpy(f.data, bytes + 8, length);
  out = f;
  return nullptr;
}

void encode_can_frame(const CanFrame& frame, std::uint8_t* bytes) noexcept {
  std::uint32_t raw_id = frame.extended ? (frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG : frame.id & CAN_SFF_MASK;
  if (frame.error) raw_id = (frame.id & CAN_ERR_MASK) | CAN_ERR_FLAG | (frame.extended ? CAN_EFF_FLAG : 0u);
  if (frame.remote) raw_id |= CAN_RTR_FLAG;
  std::memset(bytes, 0, kCanFrameBytes);
  std::memcpy(bytes, &raw_id, sizeof raw_id);
  const std::uint8_t length = frame.length > 8 ? 8 : frame.length;
  bytes[4] = length;
  if (!frame.remote) std::memcpy(bytes + 8, frame.data, length);
}

CanErrorSummary summarize_error(const CanFrame& f) noexcept {
  CanErrorSummary s;
  if (!f.error) return s;
  const std::uint32_t cls = f.id;
  const std::uint8_t controller = f.length > 1 ? f.data[1] : 0;
  s.bus_off = (cls & CAN_ERR_BUSOFF) != 0;
  s.tx_timeout = (cls & CAN_ERR_TX_TIMEOUT) != 0;
  s.lost_arbitration = (cls & CAN_ERR_LOSTARB) != 0;
  s.protocol_violation = (cls & CAN_ERR_PROT) != 0;
  s.no_ack = (cls & CAN_ERR_ACK) != 0;
  s.restarted = (cls & CAN_ERR_RESTARTED) != 0;
  if (cls & CAN_ERR_CRTL) {
    s.error_passive = (controller & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0;
    s.warning = (controller & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0;
    s.rx_overflow = (controller & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0;
  }
  s.worst = s.bus_off              ? "CAN bus-off: the controller left the bus"
            : s.error_passive      ? "CAN controller error-passive (error counters over 127)"
            : s.no_ack             ? "CAN frames not acknowledged (no other node on the bus?)"
            : s.tx_timeout         ? "CAN transmit timeout"
            : s.rx_overflow        ? "CAN controller buffer overflow: frames lost"
            : s.protocol_violation ? "CAN protocol violation"
            : s.restarted          ? "CAN controller restarted after bus-off"
            : s.warning            ? "CAN controller error warning (error counters over 96)"
            : s.lost_arbitration   ? "CAN arbitration lost"
                                   : "";
  return s;
}

}  // namespace lode::hal
