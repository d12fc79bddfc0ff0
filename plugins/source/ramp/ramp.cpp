#include "ramp.hpp"

#include <algorithm>

#include "../common/source_elements.hpp"
#include "lode/plugin.hpp"

namespace lode::plugins {

Status RampSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  source::SourceElements elements = source::read_source_elements(params);
  size_ = elements.size();
  offset_ = elements.offset;
  rate_ = source::read_per_element(params, "rate", size_);
  start_ns_ = source::read_time_ns(params, "start_s", 0.0);
  has_duration_ = params.has("duration_s");
  if (has_duration_) duration_ns_ = source::read_time_ns(params, "duration_s");
  else params.number("duration_s", 0.0);  // record the optional key as read

  ctx.declare_output(out_, "out", elements.elements);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status RampSource::activate() {
  for (std::size_t i = 0; i < size_; ++i) out_[i] = offset_[i];
  return Status::ok();
}

StepStatus RampSource::step(const Tick& tick) noexcept {
  // Clamp the elapsed time in integer nanoseconds: exact start and hold instants.
  std::int64_t ramp_ns = std::max<std::int64_t>(tick.time_ns - start_ns_, 0);
  if (has_duration_) ramp_ns = std::min(ramp_ns, duration_ns_);
  const double ramp_s = static_cast<double>(ramp_ns) * 1e-9;
  for (std::size_t i = 0; i < size_; ++i) out_[i] = offset_[i] + rate_[i] * ramp_s;
  return StepStatus::ok;
}

void RampSource::describe(Json& out) const {
  out["elements"] = static_cast<int>(size_);
  out["offset"] = offset_;
  out["rate_per_s"] = rate_;
  out["start_s"] = static_cast<double>(start_ns_) * 1e-9;
  if (has_duration_) {
    out["duration_s"] = static_cast<double>(duration_ns_) * 1e-9;
    std::vector<double> final_value(size_);
    for (std::size_t i = 0; i < size_; ++i)
      final_value[i] = offset_[i] + rate_[i] * static_cast<double>(duration_ns_) * 1e-9;
    out["final_value"] = final_value;
  } else {
    out["duration_s"] = nullptr;
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"names", "list<text>", nullptr, "output element names, e.g. [theta_z]"},
    {"units", "list<text>", nullptr, "SI unit per element, e.g. [rad]"},
    {"offset", "list<number>", "0 per element", "value before the start [element unit]"},
    {"rate", "list<number>", nullptr, "slope per element [element unit / s]"},
    {"start_s", "number", "0", "scheduled time at which the ramp starts [s], >= 0"},
    {"duration_s", "number", "none (ramp forever)", "ramp length [s]; the value holds after"},
};

constexpr PortDoc kPorts[] = {
    {"out", "out", "ramp reference, elements from names/units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::RampSource, "source.ramp", lode::PluginKind::block, "0.1.0",
            "Constant-rate ramp reference with optional duration and hold",
            lode::plugins::kParams, lode::plugins::kPorts)
