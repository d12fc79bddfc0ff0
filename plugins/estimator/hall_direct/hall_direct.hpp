// estimator.hall_direct: the paper's "direct measurement" (the baseline "standard method" of
// Sensors 2016, 16, 1504): the magnet distance from the Hall voltage through the static
// characteristic with coil-voltage compensation, no filtering (eq. 14-16).
//
// @system
// name: estimator.hall_direct
// input_ports:
//   signals:      >= 1 element; the Hall channel by name (`channel`)     # e.g. stage.signals: hall [V]
//   coil_voltage: optional; the element named coil_voltage [V] (or the only element)
//                                          # e.g. stage.truth: the coil voltage held at the sample
// output_ports:
//   gap:         1, `output_name` [m]      # d_hall (eq. 14)
//   compensated: 1, compensated [V]        # C_H (eq. 15), before clamping
// @endsystem
//
//   C_H    = v_hall - (1.299e-6 v^2 + 9.05e-5 v + 2.544)        (eq. 15, bracketed: sensor.hall_gap README)
//   d_hall = 1e-3 M_H(clamp(C_H, 0, 0.8))  [m]                  (eq. 14, 16; M_H in mm)
// With the coil_voltage input unconnected, v = 0 (only the quiescent 2.544 V is removed).
// The polynomial is the one sensor.hall_gap inverts (the sensor family's hall_polynomial.hpp), so the simulated
// sensor and this conversion are exact inverses when their parameters agree.
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

#include "hall_polynomial.hpp"
#include "lode/sdk/block.hpp"

namespace lode::plugins {

class HallDirect final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

  /// Samples whose C_H fell outside the valid range (and were clamped) since activate().
  [[nodiscard]] std::uint64_t clamp_count() const noexcept { return clamps_.load(std::memory_order_relaxed); }

 private:
  hall::Conversion conversion_ = hall::Conversion::paper();
  std::string channel_ = "hall";
  std::string output_name_ = "gap";
  std::size_t hall_index_ = 0;
  std::size_t coil_index_ = 0;
  bool use_coil_voltage_ = false;

  InputPort signals_;
  InputPort coil_voltage_;
  OutputPort gap_;
  OutputPort compensated_;

  std::atomic<std::uint64_t> clamps_{0};
};

}  // namespace lode::plugins
