#include "ramp.hpp"

#include <algorithm>

#include "../common/source_elements.hpp"
#include "lode/sdk/plugin.hpp"

namespace lode::plugins {

Status RampSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  source::SourceElements elements = source::read_source_elements(params);
  size_ = elements.size();
  offset_ = elements.offset;
  rate_ = source::read_per_element(params, "rate", size_);
  elements_ = elements.elements;
  rate_origin_ns_.assign(size_, 0);
  value_at_origin_.assign(size_, 0.0);
  tunables_.add({"offset", "", "", -1e300, 1e300, "value before the start, added to the ramp"});
  tunables_.add({"rate", "/s", "", -1e300, 1e300, "slope from the next sample on (output continuous)"});
  start_ns_ = source::read_time_ns(params, "start_s", 0.0);
  has_duration_ = params.has("duration_s");
  if (has_duration_) duration_ns_ = source::read_time_ns(params, "duration_s");
  else params.number("duration_s", 0.0);  // record the optional key as read

  ctx.declare_output(out_, "out", elements.elements);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status RampSource::activate() {
  for (std::size_t i = 0; i < size_; ++i) {
    out_[i] = offset_[i];
    rate_origin_ns_[i] = 0;
    value_at_origin_[i] = 0.0;
  }
  last_ramp_ns_ = 0;
  return Status::ok();
}

StepStatus RampSource::step(const Tick& tick) noexcept {
  // Clamp the elapsed time in integer nanoseconds: exact start and hold instants.
  std::int64_t ramp_ns = std::max<std::int64_t>(tick.time_ns - start_ns_, 0);
  if (has_duration_) ramp_ns = std::min(ramp_ns, duration_ns_);
  last_ramp_ns_ = ramp_ns;
  for (std::size_t i = 0; i < size_; ++i) {
    const double since_origin_s = static_cast<double>(ramp_ns - rate_origin_ns_[i]) * 1e-9;
    out_[i] = offset_[i] + value_at_origin_[i] + rate_[i] * since_origin_s;
  }
  return StepStatus::ok;
}

std::vector<Tunable> RampSource::tunables() const { return tunables_.list(elements_); }

double RampSource::tunable_value(std::size_t index) const noexcept {
  std::size_t group = 0, element = 0;
  if (!tunables_.locate(index, size_, group, element)) return 0.0;
  return group == 0 ? offset_[element] : rate_[element];
}

bool RampSource::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  std::size_t group = 0, element = 0;
  if (!tunables_.locate(index, size_, group, element)) {
    why = "no such parameter";
    return false;
  }
  if (!source::accept_finite(value, why)) return false;
  if (group == 0) {
    offset_[element] = value;  // the whole ramp shifts: that is what a new offset means
    return true;
  }
  // Bend the ramp at the last sample: what the old rate produced up to there is kept.
  value_at_origin_[element] +=
      rate_[element] * static_cast<double>(last_ramp_ns_ - rate_origin_ns_[element]) * 1e-9;
  rate_origin_ns_[element] = last_ramp_ns_;
  rate_[element] = value;
  return true;
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
      final_value[i] = offset_[i] + value_at_origin_[i] +
                       rate_[i] * static_cast<double>(duration_ns_ - rate_origin_ns_[i]) * 1e-9;
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

constexpr PortSpec kPorts[] = {
    {"out", PortDirection::out, "ramp reference, elements from names/units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::RampSource, "source.ramp", lode::PluginKind::source, "0.1.0",
            "Constant-rate ramp reference with optional duration and hold",
            lode::plugins::kParams, lode::plugins::kPorts)
