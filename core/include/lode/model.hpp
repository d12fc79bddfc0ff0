// Plant and measurement models: plugins used twice.
//
// The simulated board (io.sim) runs a PlantModel forward and feeds its outputs through
// MeasurementModels to make synthetic sensor signals; estimators use a MeasurementModel
// for h(x) and its Jacobian. The simulator may be given a richer "true" model than the
// estimator (DESIGN.md §3). All evaluation methods are RT-safe: no allocation, no throw.
#pragma once

#include "lode/component.hpp"
#include "lode/json.hpp"
#include "lode/params.hpp"
#include "lode/port.hpp"
#include "lode/status.hpp"

namespace lode {

class PlantModel : public Component {
 public:
  /// Off the RT thread: read parameters, size the state.
  virtual Status configure(Params& params) = 0;
  /// Actuator inputs, e.g. fx [N], fy [N], tz [N*m].
  [[nodiscard]] virtual const Elements& inputs() const = 0;
  /// Measured outputs (the true configuration), e.g. x [m], y [m], theta_z [rad].
  [[nodiscard]] virtual const Elements& outputs() const = 0;
  /// Back to the configured initial condition.
  virtual void reset() noexcept = 0;
  /// Integrate over dt_s with inputs u held constant (zero-order hold, as a DAC does).
  virtual void advance(double dt_s, const double* u) noexcept = 0;
  virtual void output(double* y) const noexcept = 0;
  /// Full state (for recording/inspection): names and values.
  [[nodiscard]] virtual const Elements& state_elements() const = 0;
  virtual void state(double* x) const noexcept = 0;
  virtual void describe(Json& /*out*/) const {}
};

class MeasurementModel : public Component {
 public:
  virtual Status configure(Params& params) = 0;
  /// The configuration it depends on, e.g. x [m], y [m], theta_z [rad].
  [[nodiscard]] virtual const Elements& state_elements() const = 0;
  /// The signals it predicts, e.g. a1, b1, c1, d2 [V].
  [[nodiscard]] virtual const Elements& channels() const = 0;
  /// y = h(state).
  virtual void evaluate(const double* state, double* y) const noexcept = 0;
  /// y = h(state) and H = dh/dstate, row-major channels() x state_elements().
  virtual void jacobian(const double* state, double* y, double* H) const noexcept = 0;
  virtual void describe(Json& /*out*/) const {}
};

}  // namespace lode
