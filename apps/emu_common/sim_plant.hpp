// The plant behind a board emulator (lode-vme-emu, lode-can-emu): the io.sim block of
// a simulation pipeline, hosted on its own, so an emulated board's inputs read what the
// simulated stage and its sensors would give and its outputs drive that stage.
//
//   auto plant = SimPlant::open("config/kawato_planar.yaml", "stage", dac_elements, adc_names);
//   std::span<const double> volts = (*plant)->sample_after({});      // trigger 0: sample only
//   volts = (*plant)->sample_after(commands);                        // one period, then sample
//
// Timing is that of io.sim in a pipeline: the sample of trigger k+1 is the first to show the
// command latched after trigger k.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "lode/sdk/testing/block_host.hpp"
#include "lode/sdk/status.hpp"

namespace lode::emu {

class SimPlant {
 public:
  /// The io.sim block `block` of SIM_FILE, configured with `command` as its command input.
  /// Its `signals` must be `signal_names`, in order. Errors name the file and what differs.
  static Expected<std::unique_ptr<SimPlant>> open(const std::string& sim_file, const std::string& block,
                                                  const Elements& command,
                                                  const std::vector<std::string>& signal_names);

  /// Advance one period under `command` (skipped on the first call: the first trigger only
  /// samples), then sample. The io.sim block's `signals`, in its units.
  std::span<const double> sample_after(std::span<const double> command);

  [[nodiscard]] std::uint64_t faults() const { return faults_; }
  [[nodiscard]] double rate_hz() const { return rate_hz_; }

 private:
  SimPlant(std::unique_ptr<BlockHost> host, double rate_hz) : host_(std::move(host)), rate_hz_(rate_hz) {}

  std::unique_ptr<BlockHost> host_;
  double rate_hz_;
  bool first_ = true;
  std::uint64_t faults_ = 0;
};

}  // namespace lode::emu
