// The board side of regmap.hpp: plays the Pentek-like ADC/DAC pair on a register window (a
// shared-memory file the host maps too), its registers where a Layout puts them (the default
// map or one parsed from a file), so io.vme_pentek runs without hardware.
// What the ADC converts comes from a front end: in tests a loopback or a fixed signal, in
// lode-vme-emu a simulated plant with its measurement models.
//
// Faults for tests: `silent` (the board stops answering: doorbells stay set, nothing
// changes), `error_bits` (STATUS error bits set on every conversion), `never_complete`
// (BUSY forever after a trigger), `no_answer` (reads return all ones, as an absent board on
// a VME bridge).
//
// Threads: poll() is the board; call it from one thread (start() runs it on its own).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "lode/hal/register_window.hpp"
#include "lode/sdk/status.hpp"
#include "regmap.hpp"

namespace lode::vme {

class PentekEmulator {
 public:
  enum class Fault : int { none, silent, error_bits, never_complete, no_answer };
  /// One conversion: the DAC codes now latched in, the ADC codes to present out.
  using Frontend = std::function<void(const std::vector<std::uint32_t>& dac, std::vector<std::uint32_t>& adc)>;

  /// Creates the window file if needed (zero-filled, layout.window bytes past `offset`) and
  /// presents an idle board: id, channel counts, STATUS 0.
  static Expected<std::unique_ptr<PentekEmulator>> create(const std::string& path, std::uint64_t offset,
                                                           const Layout& layout, std::size_t adc_channels,
                                                           std::size_t dac_channels, Frontend frontend,
                                                           std::uint32_t revision = 1);
  ~PentekEmulator();
  PentekEmulator(const PentekEmulator&) = delete;
  PentekEmulator& operator=(const PentekEmulator&) = delete;

  /// Act on the doorbells once. Returns true when it did something.
  bool poll();
  /// Poll on a thread of its own until stop() (or destruction).
  void start();
  void stop();

  void set_fault(Fault fault, std::uint32_t error_bits = 0);
  [[nodiscard]] std::uint64_t conversions() const { return conversions_.load(); }
  [[nodiscard]] std::uint64_t dac_loads() const { return dac_loads_.load(); }
  /// The DAC codes latched by the last DAC_LOAD (what the outputs drive).
  [[nodiscard]] std::vector<std::uint32_t> latched_dac() const;

 private:
  PentekEmulator() = default;

  hal::RegisterWindow window_;
  Layout layout_;
  std::size_t adc_channels_ = 0, dac_channels_ = 0;
  std::uint32_t board_id_ = 0;
  Frontend frontend_;
  std::vector<std::uint32_t> dac_latched_, adc_codes_;
  std::vector<std::atomic<std::uint32_t>> dac_published_;  // latched codes, readable from any thread
  std::uint32_t sequence_ = 0;
  std::atomic<int> fault_{0};
  std::atomic<std::uint32_t> fault_bits_{0};
  std::atomic<std::uint64_t> conversions_{0}, dac_loads_{0};
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace lode::vme
