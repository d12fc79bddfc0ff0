#include "lode/hal/canopen.hpp"

namespace lode::hal::canopen {

CanFrame nmt_frame(NmtCommand command, int node) noexcept {
  CanFrame f;
  f.id = kNmt;
  f.length = 2;
  f.data[0] = static_cast<std::uint8_t>(command);
  f.data[1] = static_cast<std::uint8_t>(node);
  return f;
}

CanFrame sync_frame() noexcept {
  CanFrame f;
  f.id = kSync;
  return f;
}

CanFrame heartbeat_frame(int node, NmtState state) noexcept {
  CanFrame f;
  f.id = heartbeat_cob(node);
  f.length = 1;
  f.data[0] = static_cast<std::uint8_t>(state);
  return f;
}

const char* to_string(NmtState state) noexcept {
  switch (state) {
    case NmtState::boot_up: return "boot-up";
    case NmtState::stopped: return "stopped";
    case NmtState::operational: return "operational";
    case NmtState::pre_operational: return "pre-operational";
  }
  return "?";
}

bool decode_heartbeat(const CanFrame& frame, NmtState& state) noexcept {
  if (frame.error || frame.remote || frame.extended || frame.length != 1) return false;
  const std::uint8_t s = frame.data[0] & 0x7f;  // bit 7 is the toggle bit of node guarding
  if (s != 0x00 && s != 0x04 && s != 0x05 && s != 0x7f) return false;
  state = static_cast<NmtState>(s);
  return true;
}

bool decode_emergency(const CanFrame& frame, Emergency& out) noexcept {
  if (frame.error || frame.remote || frame.extended || frame.length != 8) return false;
  out.error_code = static_cast<std::uint16_t>(frame.data[0] | (frame.data[1] << 8));
  out.error_register = frame.data[2];
  for (int i = 0; i < 5; ++i) out.vendor[i] = frame.data[3 + i];
  return true;
}

std::size_t PdoMapping::bytes() const noexcept {
  std::size_t bits = 0;
  for (const auto& e : entries) bits += static_cast<std::size_t>(e.bits);
  return bits / 8;
}

Status validate(const PdoMapping& m) {
  if (m.pdo < 1 || m.pdo > 4) return Status::error("pdo must be 1 ... 4, got " + std::to_string(m.pdo));
  if (m.entries.empty()) return Status::error("PDO " + std::to_string(m.pdo) + " maps nothing");
  std::size_t bits = 0;
  for (const auto& e : m.entries) {
    if (e.bits != 8 && e.bits != 16 && e.bits != 32)
      return Status::error("PDO " + std::to_string(m.pdo) + " entry '" + e.name + "': bits must be 8, 16 or 32, got " +
                           std::to_string(e.bits));
    bits += static_cast<std::size_t>(e.bits);
  }
  if (bits > 64)
    return Status::error("PDO " + std::to_string(m.pdo) + " maps " + std::to_string(bits) +
                         " bits: a CAN frame carries at most 64");
  return {};
}

const char* unpack_pdo(const PdoMapping& m, const CanFrame& frame, std::int64_t* raw) noexcept {
  if (frame.error || frame.remote) return "not a data frame";
  if (frame.length != m.bytes()) return "PDO length does not match its mapping";
  std::size_t byte = 0;
  for (std::size_t i = 0; i < m.entries.size(); ++i) {
    const int bits = m.entries[i].bits;
    std::uint64_t v = 0;
    for (int b = 0; b < bits / 8; ++b) v |= static_cast<std::uint64_t>(frame.data[byte + static_cast<std::size_t>(b)]) << (8 * b);
    byte += static_cast<std::size_t>(bits / 8);
    if (m.entries[i].is_signed && (v >> (bits - 1)) != 0) v |= ~std::uint64_t{0} << bits;  // sign-extend
    raw[i] = static_cast<std::int64_t>(v);
  }
  return nullptr;
}

void pack_pdo(const PdoMapping& m, const std::int64_t* raw, CanFrame& frame) noexcept {
  std::size_t byte = 0;
  for (std::size_t i = 0; i < m.entries.size() && byte < 8; ++i) {
    const auto v = static_cast<std::uint64_t>(raw[i]);
    for (int b = 0; b < m.entries[i].bits / 8 && byte < 8; ++b) frame.data[byte++] = static_cast<std::uint8_t>(v >> (8 * b));
  }
  frame.length = static_cast<std::uint8_t>(byte);
  frame.remote = false;
  frame.error = false;
}

}  // namespace lode::hal::canopen
