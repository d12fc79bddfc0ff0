// CANopen pieces a DAQ backend needs (hal/; CiA 301): the predefined connection set
// (COB-IDs of NMT, SYNC, EMCY, PDOs, heartbeat), NMT commands, heartbeat states, EMCY
// messages, and a PDO codec for a static mapping of integer objects packed little endian.
//
//   PdoMapping tpdo1;                     // what the module sends: two 16-bit signed inputs
//   tpdo1.entries = {{"a1", 16, true}, {"b1", 16, true}};
//   if (auto st = validate(tpdo1); !st) ...
//   std::int64_t raw[2];
//   if (const char* why = unpack_pdo(tpdo1, frame, raw)) ...   // e.g. a wrong length
//
// pack/unpack/decode are noexcept and allocation-free (the RT path uses them).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lode/hal/can_frame.hpp"
#include "lode/sdk/status.hpp"

namespace lode::hal::canopen {

// Predefined connection set: function code + node id (1..127).
inline constexpr std::uint32_t kNmt = 0x000;
inline constexpr std::uint32_t kSync = 0x080;
inline constexpr std::uint32_t kEmcyBase = 0x080;
inline constexpr std::uint32_t kHeartbeatBase = 0x700;
[[nodiscard]] constexpr std::uint32_t tpdo_cob(int pdo, int node) noexcept { return 0x180u + 0x100u * static_cast<std::uint32_t>(pdo - 1) + static_cast<std::uint32_t>(node); }
[[nodiscard]] constexpr std::uint32_t rpdo_cob(int pdo, int node) noexcept { return 0x200u + 0x100u * static_cast<std::uint32_t>(pdo - 1) + static_cast<std::uint32_t>(node); }
[[nodiscard]] constexpr std::uint32_t emcy_cob(int node) noexcept { return kEmcyBase + static_cast<std::uint32_t>(node); }
[[nodiscard]] constexpr std::uint32_t heartbeat_cob(int node) noexcept { return kHeartbeatBase + static_cast<std::uint32_t>(node); }

enum class NmtCommand : std::uint8_t { start = 0x01, stop = 0x02, pre_operational = 0x80, reset_node = 0x81, reset_communication = 0x82 };
enum class NmtState : std::uint8_t { boot_up = 0x00, stopped = 0x04, operational = 0x05, pre_operational = 0x7f };

[[nodiscard]] CanFrame nmt_frame(NmtCommand command, int node) noexcept;  ///< node 0 = all
[[nodiscard]] CanFrame sync_frame() noexcept;
[[nodiscard]] CanFrame heartbeat_frame(int node, NmtState state) noexcept;
[[nodiscard]] const char* to_string(NmtState state) noexcept;

/// A heartbeat frame's state, or nullptr-reason style: returns false if `frame` is not a
/// valid heartbeat (length 1, a known state).
[[nodiscard]] bool decode_heartbeat(const CanFrame& frame, NmtState& state) noexcept;

struct Emergency {
  std::uint16_t error_code = 0;    ///< 0x0000 = error reset / no error
  std::uint8_t error_register = 0;
  std::uint8_t vendor[5] = {};
};
/// An EMCY frame (8 bytes); false if it is not one.
[[nodiscard]] bool decode_emergency(const CanFrame& frame, Emergency& out) noexcept;

/// One mapped object of a PDO: `bits` 8, 16 or 32, packed in order from byte 0.
struct PdoEntry {
  std::string name;
  int bits = 16;
  bool is_signed = true;
};

struct PdoMapping {
  int pdo = 1;                     ///< 1..4
  std::vector<PdoEntry> entries;   ///< at most 64 bits in all
  [[nodiscard]] std::size_t bytes() const noexcept;
};

/// Why the mapping cannot be used ("" = fine): bits not 8/16/32, over 8 bytes, no entry, pdo
/// not 1..4.
[[nodiscard]] Status validate(const PdoMapping& mapping);

/// The mapped objects of `frame` into `raw` (one per entry, sign-extended where signed).
/// Returns nullptr, or why not (remote or error frame, a length other than the mapping's).
[[nodiscard]] const char* unpack_pdo(const PdoMapping& mapping, const CanFrame& frame, std::int64_t* raw) noexcept;

/// `raw` (one per entry) packed into `frame.data` and `frame.length`; values are truncated to
/// their width (the caller clips to the range first). The identifier is left to the caller.
void pack_pdo(const PdoMapping& mapping, const std::int64_t* raw, CanFrame& frame) noexcept;

}  // namespace lode::hal::canopen
