// Plant and measurement models: plugins used twice.
//
// The simulated board (io.sim) runs a PlantModel forward and feeds its outputs through
// MeasurementModels to make synthetic sensor signals; estimators use a MeasurementModel
// for h(x) and its Jacobian. The simulator may be given a richer "true" model than the
// estimator. All evaluation methods are RT-safe: no allocation, no throw.
//
// A model names its vectors once, off the RT thread, with the protected declare_*_elements()
// call of each interface it implements (in its constructor when the layout is fixed, in
// configure() when the parameters shape it); the accessors return what it declared.
#pragma once

#include <cstddef>
#include <utility>

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
  [[nodiscard]] const Elements& inputs() const { return inputs_; }
  /// Measured outputs (the true configuration), e.g. x [m], y [m], theta_z [rad].
  [[nodiscard]] const Elements& outputs() const { return outputs_; }
  /// Back to the configured initial condition.
  virtual void reset() noexcept = 0;
  /// Integrate over dt_s with inputs u held constant (zero-order hold, as a DAC does).
  virtual void advance(double dt_s, const double* u) noexcept = 0;
  virtual void output(double* y) const noexcept = 0;
  /// Full state (for recording/inspection): names and values.
  [[nodiscard]] const Elements& state_elements() const { return state_elements_; }
  virtual void state(double* x) const noexcept = 0;
  virtual void describe(Json& /*out*/) const {}

 protected:
  /// What inputs(), outputs() and state_elements() return. Off the RT thread.
  void declare_plant_elements(Elements inputs, Elements outputs, Elements state) {
    inputs_ = std::move(inputs);
    outputs_ = std::move(outputs);
    state_elements_ = std::move(state);
  }

 private:
  Elements inputs_;
  Elements outputs_;
  Elements state_elements_;
};

class MeasurementModel : public virtual Component {
 public:
  virtual Status configure(Params& params) = 0;
  /// The configuration it depends on, e.g. x [m], y [m], theta_z [rad].
  [[nodiscard]] const Elements& state_elements() const { return state_elements_; }
  /// The signals it predicts, e.g. a1, b1, c1, d2 [V].
  [[nodiscard]] const Elements& channels() const { return channels_; }
  /// y = h(state).
  virtual void evaluate(const double* state, double* y) const noexcept = 0;
  /// y = h(state) and H = dh/dstate, row-major channels() x state_elements().
  virtual void jacobian(const double* state, double* y, double* H) const noexcept = 0;
  /// evaluate() at `count` states, the i-th at states + i * stride (stride >=
  /// state_elements().size()), the i-th result at y + i * channels().size(). What a sigma-point
  /// filter asks for every point of a step: a model overrides it to evaluate the points in
  /// one loop instead of a virtual call each, with evaluate()'s operations for every point
  /// (the same results). RT-safe.
  virtual void evaluate_points(const double* states, std::size_t stride, std::size_t count,
                               double* y) const noexcept {
    const std::size_t m = channels().size();
    for (std::size_t i = 0; i < count; ++i) evaluate(states + i * stride, y + i * m);
  }
  virtual void describe(Json& /*out*/) const {}

 protected:
  /// What state_elements() and channels() return. Off the RT thread.
  void declare_measurement_elements(Elements state, Elements channels) {
    state_elements_ = std::move(state);
    channels_ = std::move(channels);
  }

 private:
  Elements state_elements_;
  Elements channels_;
};

/// A discrete-time process model x_{k+1} = f(x_k, u_k) for estimators (EKF, UKF).
///
/// Stateless: the estimator owns the state. A plant plugin may implement both PlantModel
/// (the simulator's truth, with its own state) and ProcessModel (the estimator's f), so
/// one set of physics serves both; Component is a virtual base for that reason. Such a
/// plugin declares the elements of both interfaces.
class ProcessModel : public virtual Component {
 public:
  virtual Status configure(Params& params) = 0;
  /// State layout, e.g. gap [m], velocity [m/s], current [A].
  [[nodiscard]] const Elements& process_state() const { return process_state_; }
  /// Known inputs u (may be empty), e.g. voltage [V].
  [[nodiscard]] const Elements& process_inputs() const { return process_inputs_; }
  /// x_next = f(x, u) over dt_s. RT-safe.
  virtual void propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept = 0;
  /// propagate() for `count` states laid out one after another (process_state().size() each),
  /// into x_next in the same layout (x_next may not overlap x). What a sigma-point filter asks
  /// for every point of a step: a model overrides it to run the points in one loop instead of
  /// a virtual call each, with propagate()'s operations for every point (the same results).
  /// RT-safe.
  virtual void propagate_points(double dt_s, const double* x, std::size_t count, const double* u,
                                double* x_next) const noexcept {
    const std::size_t n = process_state().size();
    for (std::size_t i = 0; i < count; ++i) propagate(dt_s, x + i * n, u, x_next + i * n);
  }
  /// F = df/dx (row-major n x n) at (x, u). Returns false if the model has no analytic
  /// Jacobian (an EKF then differentiates numerically). RT-safe.
  virtual bool process_jacobian(double /*dt_s*/, const double* /*x*/, const double* /*u*/,
                                double* /*F*/) const noexcept {
    return false;
  }

 protected:
  /// What process_state() and process_inputs() return. Off the RT thread.
  void declare_process_elements(Elements state, Elements inputs) {
    process_state_ = std::move(state);
    process_inputs_ = std::move(inputs);
  }

 private:
  Elements process_state_;
  Elements process_inputs_;
};

}  // namespace lode
