// io.sim: the simulated ADC/DAC board (Kawato 2005).
//
// A plant model moved by the DAC commands, measurement models that turn the plant's true
// configuration into sensor volts, and the imperfections of a real acquisition chain:
// white Gaussian noise, mains interference, per-channel offsets and an ADC that quantizes
// and saturates.
//
// @system
// name: io.sim
// input_ports:
//   command: [plant inputs, e.g. fx N, fy N, tz N*m]   # write phase, held for one period (ZOH)
// output_ports:                                         # read phase, start of the cycle
//   signals:     [sensor channels, V]   # after offset, mains, noise and quantization
//   counts:      [sensor channels, 1]   # raw signed ADC counts (integers stored as doubles)
//   truth:       [plant outputs, e.g. x m, y m, theta_z rad]
//   plant_state: [plant state elements, e.g. x, y, theta_z, vx, vy, omega_z]
// @endsystem
//
// Cycle k: step() (read phase) samples the plant as it is at the start of the cycle; write()
// (write phase) takes the command computed in cycle k and advances the plant by one period
// with it held constant. The sample of cycle k+1 is therefore the first to show the command
// of cycle k, as on a real board.
//
// Fault injection (tests and demos): `inject_nan: {channel, start_s, duration_s}` makes one
// channel's signals AND counts NaN on the cycles whose scheduled time t satisfies
// start_s <= t < start_s + duration_s; the tunable inject_nan_channel (-1 = off) does the
// same live, on every cycle, for the channel of that index (`lode set stage.inject_nan_channel 0`).
// `inject_stuck: {channel, start_s, duration_s, value_v}` makes one channel read a constant,
// finite value in its window: value_v through the converter (a disconnected or railed
// sensor), or without value_v the reading of the last cycle before the window (a frozen
// converter). A fault that stays finite gets past a NaN check; it is what the health
// monitor's innovation test is for.
// The noise generator advances exactly as without injection, so every other channel (and the
// injected one once the window has passed) is bit for bit what it would have been.
//
// Threads: configure()/activate()/describe() on the loader thread; step()/write()/drive_safe()
// on the RT thread (no allocation: every buffer is sized in configure()). drive_safe() may also
// be called by the pipeline from the non-RT thread after the RT thread has stopped.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/tunables.hpp"
#include "sim_converter.hpp"

namespace lode::plugins {

class SimBoard final : public Block, public Tunables, public Board {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  StepStatus write(const Tick& tick) noexcept override;
  void drive_safe() noexcept override;
  void describe(Json& out) const override;

  /// `lode set`: inject_nan_channel (index 0), an integer in [-1, channels - 1], -1 = off.
  [[nodiscard]] std::vector<Tunable> tunables() const override;
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept override;
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override;

  /// ADC saturations (samples clipped to the converter's range) since activate().
  [[nodiscard]] std::uint64_t saturation_count() const noexcept {
    return saturations_.load(std::memory_order_relaxed);
  }
  /// Command elements clamped to command_limit since activate().
  [[nodiscard]] std::uint64_t command_clamp_count() const noexcept {
    return command_clamps_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] bool safe() const noexcept { return safe_.load(std::memory_order_relaxed); }

 private:
  /// One measurement model and where its inputs and outputs live.
  struct SensorSlot {
    std::string name;                        ///< name in `models:`
    ModelPtr<MeasurementModel> model;
    std::vector<std::size_t> truth_index;    ///< per model state element: plant output index
    std::size_t first_channel = 0;
    std::size_t channel_count = 0;
    bool reads_truth_prefix = false;         ///< truth_index is 0, 1, ...: no gather needed
  };

  /// A fault-injection window of the YAML: one channel (-1 = none) on the cycles whose
  /// scheduled time is in [start_ns, end_ns).
  struct FaultWindow {
    std::int64_t channel = -1;
    std::int64_t start_ns = 0;
    std::int64_t end_ns = 0;  ///< exclusive
    /// The channel it makes faulty on the cycle scheduled at time_ns, or -1.
    [[nodiscard]] std::int64_t active(std::int64_t time_ns) const noexcept {
      return channel >= 0 && time_ns >= start_ns && time_ns < end_ns ? channel : -1;
    }
    /// describe(): the channel's index, start_s, end_s and what the window means.
    [[nodiscard]] Json describe() const;
  };

  Status configure_sensors(ConfigureContext& ctx, Params& params);
  /// Fill every output from the plant's current state; noise only when `with_noise`.
  /// `in_cycle`: a scheduled cycle (noise and fault injection apply), not activate()'s sample.
  StepStatus sample(std::int64_t time_ns, bool in_cycle) noexcept;
  /// The fault injections of one cycle: each the channel it hits, or -1.
  struct Injections {
    std::int64_t stuck = -1;
    std::int64_t live_nan = -1;    ///< the tunable inject_nan_channel
    std::int64_t window_nan = -1;  ///< the YAML inject_nan window
    double previous_count = 0.0, previous_signal = 0.0;  ///< the stuck channel's last reading
    [[nodiscard]] bool any() const noexcept { return stuck >= 0 || live_nan >= 0 || window_nan >= 0; }
  };
  /// Channels [0, channels) of volts_ through the converter into counts and signals; the
  /// number of clipped samples.
  std::uint64_t convert(std::size_t channels) noexcept;
  /// The injections that hit channels [0, channels), over their readings of this cycle.
  void inject(std::size_t channels, const Injections& injections) noexcept;
  /// `{channel, start_s, duration_s}` of a fault-injection map: the channel's index (-1 when
  /// the map is invalid, which is reported) and the window [start_ns, end_ns).
  void parse_injection_window(Params& window, bool sensors_ok, FaultWindow& out);
  void advance_plant(double dt_s, const double* u) noexcept;

  // Models
  ModelPtr<PlantModel> plant_;
  std::string plant_name_;
  std::vector<SensorSlot> sensors_;

  // Sizes
  std::size_t channel_count_ = 0;
  std::size_t input_count_ = 0;

  // Parameters
  double noise_std_v_ = 1e-3;
  std::int64_t adc_bits_ = 16;
  double adc_range_v_ = 10.0;
  sim::ConverterScale converter_;  ///< lsb_v 0 without quantization (adc_bits 0)
  double mains_amplitude_v_ = 0.0;
  double mains_frequency_hz_ = 60.0;
  double mains_phase_rad_ = 0.0;
  std::vector<double> channel_offset_v_;
  std::uint64_t seed_ = 1;
  std::vector<double> safe_command_;
  std::vector<double> command_limit_;  ///< empty: no clamp
  std::int64_t substeps_ = 1;
  bool plain_write_ = true;  ///< no command_limit and one substep: write() hands the command port to the plant

  // Fault injection: the YAML window of NaN readings and the live tunable.
  FaultWindow nan_window_;
  std::atomic<std::int64_t> inject_live_channel_{-1};
  // Stuck channel (YAML window): reads stuck_count_ / stuck_signal_v_, or with
  // stuck_holds_last_ its previous cycle's reading.
  FaultWindow stuck_window_;
  bool stuck_holds_last_ = true;
  double stuck_count_ = 0.0;
  double stuck_signal_v_ = 0.0;

  // Ports
  InputPort command_;
  OutputPort signals_;
  OutputPort counts_;
  OutputPort truth_;
  OutputPort plant_state_;

  // Cycle scratch, sized in configure()
  std::vector<double> truth_buffer_;
  std::vector<double> sensor_state_;
  std::vector<double> clean_signals_;
  std::vector<double> volts_;  ///< this cycle's volts of each channel, before the converter
  std::vector<double> held_command_;

  sim::GaussianNoise noise_;

  // Health, readable from describe() while running
  std::atomic<bool> safe_{false};
  std::atomic<std::uint64_t> saturations_{0};
  bool was_saturated_ = false;
  std::string block_name_;  ///< source of rt_log records (lives as long as the block)
  std::atomic<std::uint64_t> command_clamps_{0};
};

}  // namespace lode::plugins
