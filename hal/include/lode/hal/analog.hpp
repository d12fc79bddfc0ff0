// Analog converter channels shared by the hardware backends (hal/): what one ADC or
// DAC channel of a board is (name, resolution, span, code format, calibration, unit, safe
// value) and the conversions between the board's raw codes and engineering values.
//
//   volts = span_min_v + (k - k_min) * lsb        lsb = (span_max_v - span_min_v) / 2^bits
//   value = gain * volts + offset                 (calibration; unit = the value's unit)
//
// where k is the code index: for two's complement the sign-extended field, for offset binary
// the raw field minus 2^(bits-1), for unipolar the raw field. A DAC code is the nearest one,
// clipped to the converter's range; a non-finite value becomes the channel's safe value.
// Everything after validate() is noexcept and allocation-free (the RT path uses it).
#pragma once

#include <cstdint>
#include <string>

#include "lode/sdk/status.hpp"

namespace lode::hal {

enum class Coding : std::uint8_t { twos_complement, offset_binary, unipolar };

[[nodiscard]] const char* to_string(Coding coding) noexcept;

struct AnalogChannel {
  std::string name;
  int bits = 16;               ///< converter resolution, 2..32
  double span_min_v = -10.0;   ///< the converter's range (ADC input, DAC output)
  double span_max_v = 10.0;
  Coding coding = Coding::twos_complement;
  double gain = 1.0;           ///< calibration: value = gain * volts + offset; gain != 0
  double offset = 0.0;
  std::string unit = "V";      ///< unit of the calibrated value
  double safe_value = 0.0;     ///< outputs: the value driven on any fault, stop or signal
};

/// Why the descriptor is unusable ("" when it is fine), naming the field.
[[nodiscard]] Status validate(const AnalogChannel& channel);

/// Precomputed conversions of one validated channel.
class AnalogConversion {
 public:
  AnalogConversion() = default;
  explicit AnalogConversion(const AnalogChannel& channel) noexcept;

  /// Raw register field (the low `bits` bits are used) -> calibrated value.
  [[nodiscard]] double code_to_value(std::uint32_t raw) const noexcept;
  /// Calibrated value -> raw register field, nearest code; `clipped` is set when the value
  /// lay outside the converter's range (or was not finite: then the safe value is coded).
  [[nodiscard]] std::uint32_t value_to_code(double value, bool& clipped) const noexcept;
  /// The signed code index k of a raw register field (k_min ... k_max).
  [[nodiscard]] std::int64_t code_index(std::uint32_t raw) const noexcept { return index_of(raw); }
  /// The code of the safe value (what a backend writes on a fault).
  [[nodiscard]] std::uint32_t safe_code() const noexcept { return safe_code_; }
  [[nodiscard]] double lsb_v() const noexcept { return lsb_v_; }
  /// Smallest and largest code index k.
  [[nodiscard]] std::int64_t k_min() const noexcept { return k_min_; }
  [[nodiscard]] std::int64_t k_max() const noexcept { return k_max_; }

 private:
  [[nodiscard]] std::int64_t index_of(std::uint32_t raw) const noexcept;
  [[nodiscard]] std::uint32_t raw_of(std::int64_t k) const noexcept;

  Coding coding_ = Coding::twos_complement;
  int bits_ = 16;
  std::uint32_t mask_ = 0xffff;
  std::int64_t k_min_ = -32768, k_max_ = 32767;
  double span_min_v_ = -10.0, lsb_v_ = 20.0 / 65536.0;
  double gain_ = 1.0, offset_ = 0.0;
  std::uint32_t safe_code_ = 0;
};

}  // namespace lode::hal
