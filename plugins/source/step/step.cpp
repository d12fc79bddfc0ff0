#include "step.hpp"

#include <algorithm>
#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

Status StepSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  output_.read(params, "output before the first step");
  const std::size_t size = output_.size();

  const std::vector<Params> steps = params.items("steps");
  for (std::size_t i = 0; i < steps.size(); ++i) {
    Params step = steps[i];
    const std::int64_t time_ns = source::read_time_ns(step, "time_s");
    const std::vector<double> value = source::read_per_element(step, "value", size);
    if (!step_time_ns_.empty() && time_ns <= step_time_ns_.back()) {
      step.fail("time_s", "steps must be sorted by strictly increasing time_s; " +
                              number_text(static_cast<double>(time_ns) * 1e-9) +
                              " s does not come after " +
                              number_text(static_cast<double>(step_time_ns_.back()) * 1e-9) +
                              " s");
    }
    step_time_ns_.push_back(time_ns);
    step_values_.insert(step_values_.end(), value.begin(), value.end());
  }
  return output_.declare(ctx);
}

StepStatus StepSource::step(const Tick& tick) noexcept {
  // Number of steps whose time has come. Nearly always the previous cycle's: that count is
  // kept as a hint and checked against this tick's time (so any tick order still works), a
  // binary search only when it does not hold.
  const std::int64_t* times = step_time_ns_.data();
  const std::size_t steps = step_time_ns_.size();
  std::size_t reached = reached_hint_;
  if ((reached > 0 && tick.time_ns < times[reached - 1]) || (reached < steps && tick.time_ns >= times[reached])) {
    reached = static_cast<std::size_t>(std::upper_bound(times, times + steps, tick.time_ns) - times);
    reached_hint_ = reached;
  }
  const std::size_t size = output_.size();
  const double* value = reached == 0 ? output_.offset().data() : &step_values_[(reached - 1) * size];
  double* out = output_.port().data();
  for (std::size_t i = 0; i < size; ++i) out[i] = value[i];
  return StepStatus::ok;
}

void StepSource::describe(Json& out) const {
  output_.describe(out);
  const std::size_t size = output_.size();
  Json steps = Json::array();
  for (std::size_t s = 0; s < step_time_ns_.size(); ++s) {
    Json step = Json::object();
    step["time_s"] = static_cast<double>(step_time_ns_[s]) * 1e-9;
    step["value"] = std::vector<double>(step_values_.begin() + static_cast<std::ptrdiff_t>(s * size),
                                        step_values_.begin() + static_cast<std::ptrdiff_t>((s + 1) * size));
    steps.push(std::move(step));
  }
  out["steps"] = std::move(steps);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"names", "list<text>", nullptr, "output element names, e.g. [x, y, theta_z]"},
    {"units", "list<text>", nullptr, "SI unit per element, e.g. [m, m, rad]"},
    {"offset", "list<number>", "0 per element", "output before the first step [element unit]"},
    {"steps", "list<map>", nullptr,
     "{time_s: scheduled time [s] >= 0, value: [absolute value per element]}, strictly "
     "increasing time_s"},
};

constexpr PortSpec kPorts[] = {
    {"out", PortDirection::out, "piecewise-constant reference, elements from names/units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::StepSource, "source.step", lode::PluginKind::source, "0.1.0",
            "Piecewise-constant reference: absolute values at scheduled times",
            lode::plugins::kParams, lode::plugins::kPorts)
