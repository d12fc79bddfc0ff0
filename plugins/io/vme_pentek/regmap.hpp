// Register map of the Pentek-like VME ADC/DAC board pair that io.vme_pentek drives and
// lode-vme-emu plays (Kawato 2005: a Pentek 6102 A/D and a DATEL DVME622 D/A on a
// VME bus): where each register, bit and field lies in the board's window. Boards and
// firmware revisions move registers, so the map is data: a Layout, either the built-in
// default_layout() or parsed from a register-map file (pentek6102_dvme622.regmap is the
// default written out, with each register documented; README.md has the format).
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
//
// Register-map file, one directive per line, `#` starts a comment, numbers decimal or 0x hex:
//   window SIZE                                      bytes the host maps (4 ... 0x10000)
//   register NAME OFFSET ro|wo|rw [value V] [mask M] [count N] [stride S]
//   bit REGISTER.NAME BIT                            0 ... 31
//   field REGISTER.NAME LO..HI                       0 <= LO <= HI <= 31
// Access is the host's: ro read only, wo write only, rw both (the doorbells are rw: the host
// sets them and reads them back). count/stride make an array of 32-bit registers at
// OFFSET + STRIDE * i. `value`/`mask` give a constant the host checks (BOARD_ID).
// Registers, bits and fields beyond the ones below may be declared (documentation of the
// rest of the board); they are checked like the others and otherwise ignored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "lode/sdk/status.hpp"

namespace lode::vme {

/// A read of all ones: nobody answered the bus cycle (no board, or the bridge timed out).
inline constexpr std::uint32_t kNoAnswer = 0xffffffffu;

/// Limits of the file format (and so of what a fuzzer can make the parser allocate).
inline constexpr std::size_t kMaxWindow = 0x10000;       ///< bytes: a 64 KiB slave window
inline constexpr std::size_t kMaxMapFileBytes = 1 << 20;  ///< load_layout() refuses larger files
inline constexpr std::size_t kMaxRegisters = 256;         ///< register directives per file
inline constexpr std::size_t kMaxBits = 1024;             ///< bit + field directives per file

/// Bits LO..HI (inclusive) of a 32-bit register.
struct BitField {
  unsigned lo = 0, hi = 0;

  [[nodiscard]] constexpr std::uint32_t mask() const noexcept {
    if (lo > hi || hi > 31) return 0;  // not a field (the parser never makes one)
    return static_cast<std::uint32_t>((~0ull >> (63 - (hi - lo))) << lo);
  }
  [[nodiscard]] constexpr std::uint32_t get(std::uint32_t reg) const noexcept { return (reg & mask()) >> lo; }
  /// `value` placed in the field (high bits that do not fit are dropped: a counter wraps).
  [[nodiscard]] constexpr std::uint32_t put(std::uint32_t value) const noexcept { return (value << lo) & mask(); }
  [[nodiscard]] constexpr std::uint32_t max() const noexcept { return mask() >> lo; }
  bool operator==(const BitField&) const = default;
};

/// COUNT 32-bit registers at OFFSET + STRIDE * i.
struct RegisterArray {
  std::size_t offset = 0, count = 0, stride = 4;

  [[nodiscard]] constexpr std::size_t at(std::size_t i) const noexcept { return offset + stride * i; }
  bool operator==(const RegisterArray&) const = default;
};

/// Everything io.vme_pentek and the emulator need of the board's registers. Offsets in bytes
/// from the start of the window; bits as masks (one bit set).
struct Layout {
  std::size_t window = 0;  ///< bytes the host maps

  std::size_t board_id = 0;      ///< RO  board_id_value | revision
  std::size_t control = 0;       ///< RW  ENABLE, EXT_TRIGGER (written at activation)
  std::size_t status = 0;        ///< RO  DONE, BUSY, error bits, SEQUENCE
  std::size_t channels = 0;      ///< RO  the board's ADC and DAC channel counts
  std::size_t trigger = 0;       ///< doorbell: host 1 = convert now; board 0 = taken
  std::size_t dac_load = 0;      ///< doorbell: host 1 = latch DAC_DATA; board 0 = latched
  std::size_t reset_errors = 0;  ///< doorbell: host 1 = clear STATUS errors; board 0 = cleared
  RegisterArray adc_data, dac_data;  ///< code of channel i in the low bits

  std::uint32_t board_id_value = 0, board_id_mask = 0;

  std::uint32_t enable = 0, ext_trigger = 0;                  ///< CONTROL bits
  std::uint32_t done = 0, busy = 0;                           ///< STATUS bits
  std::uint32_t err_overrun = 0, err_adc = 0, err_dac = 0, err_bus = 0;  ///< STATUS error bits
  BitField sequence;                                          ///< STATUS: conversions, wraps
  BitField adc_channels, dac_channels;                        ///< CHANNELS fields

  /// The map the board ships with, equal to parsing pentek6102_dvme622.regmap (a test
  /// checks it).
  static Layout default_layout();

  [[nodiscard]] std::uint32_t error_mask() const noexcept { return err_overrun | err_adc | err_dac | err_bus; }

  bool operator==(const Layout&) const = default;
};

/// Parse register-map text. `file` names it in messages: each problem is one line
/// "FILE:LINE: FIELD: message" (FIELD e.g. "register STATUS", "bit CONTROL.ENABLE"), all of
/// them (up to a limit) in the error. Never throws; any input is safe.
[[nodiscard]] Expected<Layout> parse_layout(std::string_view text, const std::string& file);

/// Read and parse the file at `path` (named as given in messages).
[[nodiscard]] Expected<Layout> load_layout(const std::string& path);

/// The layout as register-map text (the required registers only), which parses back to it.
[[nodiscard]] std::string to_text(const Layout& layout);

}  // namespace lode::vme
