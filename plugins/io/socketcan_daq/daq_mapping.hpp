// The analog channels a CANopen DAQ module carries in its PDOs (io.socketcan_daq):
// each PDO entry is an integer object; value = scale * count + offset in the channel's unit.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lode/hal/canopen.hpp"

namespace lode::plugins::can_daq {

struct Channel {
  std::string name;
  std::string unit = "V";
  double scale = 1.0;        ///< unit per count
  double offset = 0.0;       ///< unit
  double safe_value = 0.0;   ///< outputs (RPDO entries): driven on any fault, stop or signal
};

/// One PDO with the channels of its entries, in order.
struct Pdo {
  hal::canopen::PdoMapping mapping;
  std::vector<Channel> channels;  ///< one per mapping entry
};

/// Count of a value for an entry: nearest integer, clipped to the entry's range; `clipped`
/// set when it was outside (or not finite: then the safe value's count).
[[nodiscard]] std::int64_t count_of(const hal::canopen::PdoEntry& entry, const Channel& channel, double value,
                                    bool& clipped) noexcept;
[[nodiscard]] inline double value_of(const Channel& channel, std::int64_t count) noexcept {
  return channel.scale * static_cast<double>(count) + channel.offset;
}

}  // namespace lode::plugins::can_daq
