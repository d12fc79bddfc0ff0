// sensor.hall_gap: the ratiometric Hall sensor (Allegro A1321) on the electromagnet face of
// the magnetic suspension of Sensors 2016, 16, 1504 (eqs. 14-16), as a measurement model.
//
// Two outputs, chosen by `output`:
//
//   hall_voltage (default; what io.sim samples): the Hall output for a magnet at `gap` while
//     the coil is driven with `coil_voltage`, the forward form of eq. 14-16:
//       C_H     = M_H^-1(1000 gap)           (inverse of eq. 16 on C_H in [0, 0.8] V)
//       v_hall  = C_H + 1.299e-6 v^2 + 9.05e-5 v + 2.544            (eq. 15, bracketed reading)
//       dv_hall/dgap = 1000 / M_H'(C_H)  [V/m],   dv_hall/dv = 2 * 1.299e-6 v + 9.05e-5
//     Outside the conversion's range (16.29 ... 46.9 mm) C_H is clamped and the reading is
//     flat (zero slope), as the static characteristic is then no longer valid (README).
//
//   gap (what an estimator fed by estimator.hall_direct sees): the direct distance d_hall of
//     eq. 14 as a function of the true gap, y = d (eq. 32, 33: "y(k) = d(k)"), saturated to the
//     conversion's range like d_hall is. The Hall nonlinearity is inverted outside the filter
//     (eq. 14).
//
// @sensor
// state:                       # what the model depends on (plant outputs, or estimator states/inputs)
//   - gap: m                   # magnet distance from the Hall sensor / electromagnet face
//   - coil_voltage: V          # hall_voltage only: the coil voltage held at the sample (eq. 15)
// channels:
//   - hall: V                  # hall_voltage: the A1321 output (name from `channel`)
//   - gap: m                   # gap: the direct distance d_hall (name from `channel`)
// @endsensor
//
// Threads: configure()/describe() on the loader thread; evaluate()/jacobian() on the RT
// thread (no allocation, no throw).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "hall_polynomial.hpp"
#include "lode/sdk/model.hpp"

namespace lode::plugins {

class HallGap final : public MeasurementModel {
 public:
  enum class Output { hall_voltage, gap };
  /// Indices into the model's state.
  enum StateIndex : std::size_t { kGap = 0, kCoilVoltage = 1 };

  HallGap();

  Status configure(Params& params) override;
  /// Use this conversion (already validated) and output; configure() ends here.
  void apply(const hall::Conversion& conversion, Output output, const std::string& channel);

  void evaluate(const double* state, double* y) const noexcept override;
  void jacobian(const double* state, double* y, double* H) const noexcept override;
  void evaluate_points(const double* states, std::size_t stride, std::size_t count, double* y) const noexcept override;
  void describe(Json& out) const override;

  [[nodiscard]] const hall::Conversion& conversion() const { return conversion_; }
  [[nodiscard]] Output output() const { return output_; }

 private:
  hall::Conversion conversion_ = hall::Conversion::paper();
  Output output_ = Output::hall_voltage;
  // The conversion's distance range [mm] (two degree-5 polynomials), taken once in apply():
  // an estimator evaluates the model at every sigma point of every step.
  double nearest_mm_ = 0.0;
  double farthest_mm_ = 0.0;
};

}  // namespace lode::plugins
