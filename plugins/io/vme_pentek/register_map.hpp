// Register map of the Pentek-like VME ADC/DAC board pair that io.vme_pentek drives and
// lode-vme-emu plays (issue 6; seed 000 §6: a Pentek 6102 A/D and a DATEL DVME622 D/A on a
// VME bus). One window of 32-bit little-endian registers; README.md has the table.
//
// Protocol, one cycle (software trigger). Each command has its own doorbell register that
// the host sets to 1 and the board clears when it has acted, so neither side ever does a
// read-modify-write of a register the other writes:
//   host:  TRIGGER = 1                                   convert every ADC channel
//   board: STATUS.BUSY while converting; then ADC_DATA[i], STATUS.SEQUENCE += 1, STATUS.DONE,
//          TRIGGER = 0
//   host:  waits for DONE with SEQUENCE advanced (else timeout), checks the STATUS error
//          bits, reads ADC_DATA[0 .. adc_channels-1]
//   ... the pipeline computes the commands ...
//   host:  DAC_DATA[i] = codes, then DAC_LOAD = 1         all DAC outputs change at once
//   board: latches DAC_DATA, DAC_LOAD = 0. A board acts on DAC_LOAD before TRIGGER, so the
//          host checks after the next conversion that DAC_LOAD is 0.
// With CONTROL.EXT_TRIGGER the board converts on its trigger input and the host only waits
// for the next SEQUENCE.
#pragma once

#include <cstddef>
#include <cstdint>

namespace lode::vme {

// Offsets (bytes from the start of the window).
inline constexpr std::size_t kBoardId = 0x000;       ///< RO  kBoardIdValue | revision (low 8 bits)
inline constexpr std::size_t kControl = 0x004;       ///< RW  bits below
inline constexpr std::size_t kStatus = 0x008;        ///< RO  bits below; SEQUENCE in bits 16..31
inline constexpr std::size_t kChannels = 0x00c;      ///< RO  ADC channels (bits 0..7), DAC channels (bits 8..15)
inline constexpr std::size_t kTrigger = 0x010;       ///< doorbell: host 1 = convert now; board 0 = done
inline constexpr std::size_t kDacLoad = 0x014;       ///< doorbell: host 1 = latch DAC_DATA; board 0 = latched
inline constexpr std::size_t kResetErrors = 0x018;   ///< doorbell: host 1 = clear STATUS errors; board 0 = cleared
inline constexpr std::size_t kAdcData = 0x100;       ///< RO  ADC_DATA[i] at kAdcData + 4 i, code in the low bits
inline constexpr std::size_t kDacData = 0x200;       ///< RW  DAC_DATA[i] at kDacData + 4 i, code in the low bits
inline constexpr std::size_t kWindowLength = 0x400;  ///< bytes the host maps
inline constexpr std::size_t kMaxChannels = 64;      ///< per direction: (0x200 - 0x100) / 4

inline constexpr std::uint32_t kBoardIdValue = 0x61020000u;  ///< "6102" in the high half
inline constexpr std::uint32_t kBoardIdMask = 0xffff0000u;

// CONTROL bits (configuration, written by the host at activation only).
inline constexpr std::uint32_t kEnable = 1u << 0;       ///< converters and outputs on
inline constexpr std::uint32_t kExtTrigger = 1u << 2;   ///< convert on the external trigger input

// STATUS bits.
inline constexpr std::uint32_t kDone = 1u << 0;         ///< the last conversion's data are valid
inline constexpr std::uint32_t kBusy = 1u << 1;         ///< converting
inline constexpr std::uint32_t kErrOverrun = 1u << 8;   ///< a trigger came while converting
inline constexpr std::uint32_t kErrAdc = 1u << 9;       ///< ADC fault (reference, clock)
inline constexpr std::uint32_t kErrDac = 1u << 10;      ///< DAC fault (output stage, over-temperature)
inline constexpr std::uint32_t kErrBus = 1u << 11;      ///< the board saw a VME bus error
inline constexpr std::uint32_t kErrorMask = kErrOverrun | kErrAdc | kErrDac | kErrBus;
inline constexpr int kSequenceShift = 16;

/// A read of all ones: nobody answered the bus cycle (no board, or the bridge timed out).
inline constexpr std::uint32_t kNoAnswer = 0xffffffffu;

[[nodiscard]] constexpr std::size_t adc_data(std::size_t channel) noexcept { return kAdcData + 4 * channel; }
[[nodiscard]] constexpr std::size_t dac_data(std::size_t channel) noexcept { return kDacData + 4 * channel; }
[[nodiscard]] constexpr std::uint32_t sequence_of(std::uint32_t status) noexcept { return status >> kSequenceShift; }

/// The first STATUS error bit's name ("" when none), for fault messages.
[[nodiscard]] constexpr const char* error_name(std::uint32_t status) noexcept {
  if (status & kErrBus) return "VME bus error";
  if (status & kErrAdc) return "ADC fault";
  if (status & kErrDac) return "DAC fault";
  if (status & kErrOverrun) return "trigger overrun";
  return "";
}

}  // namespace lode::vme
