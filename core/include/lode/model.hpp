// Plant and measurement models: plugins used twice.
//
// The simulated board (io.sim) runs a PlantModel forward and feeds its outputs through
// MeasurementModels to make synthetic sensor signals; estimators use a MeasurementModel
// for h(x) and its Jacobian. The simulator may be given a richer "true" model than the
// estimator. All evaluation methods are RT-safe: no allocation, no throw.
#pragma once

#include "lode/sdk/component.hpp"
#include "lode/sdk/json.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"
#include "lode/sdk/status.hpp"

namespace lode {

class PlantModel : public virtual Component {
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

class MeasurementModel : public virtual Component {
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

/// A discrete-time process model x_{k+1} = f(x_k, u_k) for estimators (EKF, UKF).
///
/// Stateless: the estimator owns the state. A plant plugin may implement both PlantModel
/// (the simulator's truth, with its own state) and ProcessModel (the estimator's f), so
/// one set of physics serves both; Component is a virtual base for that reason.
class ProcessModel : public virtual Component {
 public:
  virtual Status configure(Params& params) = 0;
  /// State layout, e.g. gap [m], velocity [m/s], current [A].
  [[nodiscard]] virtual const Elements& process_state() const = 0;
  /// Known inputs u (may be empty), e.g. voltage [V].
  [[nodiscard]] virtual const Elements& process_inputs() const = 0;
  /// x_next = f(x, u) over dt_s. RT-safe.
  virtual void propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept = 0;
  /// F = df/dx (row-major n x n) at (x, u). Returns false if the model has no analytic
  /// Jacobian (an EKF then differentiates numerically). RT-safe.
  virtual bool process_jacobian(double /*dt_s*/, const double* /*x*/, const double* /*u*/,
                                double* /*F*/) const noexcept {
    return false;
  }
};

}  // namespace lode
