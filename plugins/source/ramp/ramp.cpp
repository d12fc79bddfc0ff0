#include "ramp.hpp"

#include <algorithm>

#include "lode/sdk/plugin.hpp"

namespace lode::plugins {

Status RampSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  output_.read(params, "value before the start, added to the ramp");
  const std::size_t size = output_.size();
  rate_ = source::read_per_element(params, "rate", size);
  rate_origin_ns_.assign(size, 0);
  value_at_origin_.assign(size, 0.0);
  output_.add_tunable({"rate", "/s", "", -1e300, 1e300, "slope from the next sample on (output continuous)"}, rate_);
  start_ns_ = source::read_time_ns(params, "start_s", 0.0);
  has_duration_ = params.has("duration_s");
  if (has_duration_) duration_ns_ = source::read_time_ns(params, "duration_s");
  else params.number("duration_s", 0.0);  // record the optional key as read
  return output_.declare(ctx);
}

Status RampSource::activate() {
  std::fill(rate_origin_ns_.begin(), rate_origin_ns_.end(), 0);
  std::fill(value_at_origin_.begin(), value_at_origin_.end(), 0.0);
  last_ramp_ns_ = 0;
  return source::ElementSource::activate();  // out = offset
}

StepStatus RampSource::step(const Tick& tick) noexcept {
  // Clamp the elapsed time in integer nanoseconds: exact start and hold instants.
  std::int64_t ramp_ns = std::max<std::int64_t>(tick.time_ns - start_ns_, 0);
  if (has_duration_) ramp_ns = std::min(ramp_ns, duration_ns_);
  last_ramp_ns_ = ramp_ns;
  OutputPort& out = output_.port();
  const std::vector<double>& offset = output_.offset();
  for (std::size_t i = 0; i < output_.size(); ++i) {
    out[i] = offset[i] + value_at_origin_[i] + rate_[i] * source::elapsed_s(ramp_ns, rate_origin_ns_[i]);
  }
  return StepStatus::ok;
}

bool RampSource::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  std::size_t group = 0, element = 0;
  if (!output_.locate(index, value, group, element, why)) return false;
  if (group == kRate) {
    // Bend the ramp at the last sample: what the old rate produced up to there is kept.
    value_at_origin_[element] +=
        rate_[element] * static_cast<double>(last_ramp_ns_ - rate_origin_ns_[element]) * 1e-9;
    rate_origin_ns_[element] = last_ramp_ns_;
  }
  // From the next sample on; a new offset shifts the whole ramp: that is what it means.
  output_.store(group, element, value);
  return true;
}

void RampSource::describe(Json& out) const {
  output_.describe(out);
  out["rate_per_s"] = rate_;
  out["start_s"] = static_cast<double>(start_ns_) * 1e-9;
  if (has_duration_) {
    out["duration_s"] = static_cast<double>(duration_ns_) * 1e-9;
    std::vector<double> final_value(output_.size());
    for (std::size_t i = 0; i < output_.size(); ++i)
      final_value[i] = output_.offset()[i] + value_at_origin_[i] +
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
