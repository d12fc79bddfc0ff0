#include "estimator/linear_axes.hpp"

#include <string>
#include <string_view>

#include "estimator/element_names.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins::estimator {

InvalidMeasurement read_invalid_measurement(Params& params) {
  return params.choice("invalid_measurement", {"fault", "predict"}, std::string_view("fault")) == "predict"
             ? InvalidMeasurement::predict
             : InvalidMeasurement::fault;
}

const char* invalid_measurement_text(InvalidMeasurement invalid_measurement) noexcept {
  return invalid_measurement == InvalidMeasurement::predict ? "predict (the axis coasts on the time update)" : "fault";
}

Elements measured_axes(ConfigureContext& ctx) {
  Params& params = ctx.params();
  const Elements* source = ctx.input_source("measurement");
  if (source == nullptr) {
    // Not connected, or its source failed to configure (reported there).
    params.fail("inputs",
                "the measurement input must be connected to a configured block's output: its elements "
                "(names, units, count) size the filter");
    return {};
  }
  if (source->empty() || source->size() > kMaxAxes) {
    params.fail("inputs", "the measurement must have 1 to " + std::to_string(kMaxAxes) + " elements, got " +
                              std::to_string(source->size()));
    return {};
  }
  for (const Element& e : *source) {
    if (e.unit == kAnyUnit) params.fail("inputs", "measurement element '" + e.name + "' has no definite unit ('*')");
  }
  return *source;
}

void AxisOutputs::declare(ConfigureContext& ctx, const Elements& positions, bool with_acceleration) {
  ctx.declare_output(pose, "pose", positions);
  ctx.declare_output(velocity, "velocity", rate_elements(positions));
  if (with_acceleration) ctx.declare_output(acceleration, "acceleration", acceleration_elements(positions));
  ctx.declare_output(innovation, "innovation", positions);
}

StateLayout axis_state_layout(const Elements& positions, int states_per_axis) {
  StateLayout layout;
  layout.covariance = true;
  for (const Element& e : positions) {
    layout.elements.push_back({e.name, e.unit});
    layout.elements.push_back({e.name + "_dot", e.unit + "/s"});
    if (states_per_axis == 3) layout.elements.push_back({e.name + "_ddot", e.unit + "/s^2"});
  }
  return layout;
}

}  // namespace lode::plugins::estimator
