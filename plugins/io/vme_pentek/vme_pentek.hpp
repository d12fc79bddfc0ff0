// io.vme_pentek: a Pentek-like VME ADC/DAC board pair through a memory-mapped register
// window (Kawato 2005). Register map and protocol: regmap.hpp and
// README.md; the map is the built-in default or the file named by `register_map`.
//
// @system
// name: io.vme_pentek
// input_ports:
//   command: [one element per dac channel, in its unit]    # write phase, end of the cycle
// output_ports:                                            # read phase, start of the cycle
//   signals: [one element per adc channel, in its unit]    # calibrated values
//   counts:  [one element per adc channel, 1]              # signed code index k of each sample
// @endsystem
//
// Read phase (step): ring the TRIGGER doorbell (software trigger), wait for STATUS.DONE with a
// new SEQUENCE for at most conversion_timeout_us, check the STATUS error bits, read the ADC
// data. Write phase (write): DAC codes of the command, then the DAC_LOAD doorbell; the next
// read phase checks that the board latched them. Every failure is a fault with a fixed
// reason; the pipeline then calls drive_safe(), which writes every DAC channel's safe code
// and rings DAC_LOAD. deactivate() (pipeline stop, SIGTERM through the runner) does the same.
//
// Threads: configure()/activate()/deactivate() on the loader thread; step()/write()/
// drive_safe() on the RT thread: no allocation, no lock, no system call except the clock.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "acquisition_board.hpp"
#include "lode/hal/analog.hpp"
#include "lode/hal/register_window.hpp"
#include "regmap.hpp"

namespace lode::plugins {

class VmePentekBoard final : public boards::AcquisitionBoard {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  StepStatus write(const Tick& tick) noexcept override;
  void drive_safe() noexcept override;
  void deactivate() noexcept override;
  void describe(Json& out) const override;

  /// DAC values clipped to the converter's range since activate().
  [[nodiscard]] std::uint64_t dac_clips() const noexcept { return dac_clips_.load(std::memory_order_relaxed); }
  /// STATUS as last read (for messages and tests).
  [[nodiscard]] std::uint32_t last_status() const noexcept { return last_status_.load(std::memory_order_relaxed); }

 private:
  StepStatus board_fault(const char* reason, std::uint32_t status) noexcept;

  std::string device_;
  std::string register_map_;  ///< the map's file ("" = built-in default), for describe()
  vme::Layout layout_;        ///< parsed in configure(); the RT path reads only its offsets
  std::uint64_t offset_ = 0;
  bool external_trigger_ = false;
  std::int64_t conversion_timeout_ns_ = 0;
  std::vector<hal::AnalogChannel> adc_, dac_;
  std::vector<hal::AnalogConversion> adc_conv_, dac_conv_;
  hal::RegisterWindow window_;
  std::uint32_t last_sequence_ = 0;
  bool dac_load_pending_ = false;
  std::atomic<std::uint32_t> last_status_{0};
  std::atomic<std::uint64_t> dac_clips_{0};
};

}  // namespace lode::plugins
