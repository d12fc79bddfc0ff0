#include "zigzag.hpp"

#include <algorithm>
#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

Status ZigzagSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  output_.read(params, "start point of the path");
  amplitude_ = source::read_per_element(params, "amplitude", output_.size());
  advance_ = source::read_per_element(params, "advance", output_.size(), 0.0);
  output_.add_tunable({"amplitude", "", "", -1e300, 1e300, "peak of the triangle sweep above offset"}, amplitude_);
  const double period_s = params.number("period_s");
  if (!(period_s > 0.0 && period_s <= source::kMaxTimeS)) {
    params.fail("period_s", "must be within (0, 1e9] s, got " + number_text(period_s));
  } else {
    period_ns_ = source::seconds_to_ns(period_s);
    if (period_ns_ < 2) params.fail("period_s", "must be at least 2 ns");
  }
  start_ns_ = source::read_time_ns(params, "start_s", 0.0);
  advance_in_steps_ = params.choice("advance_mode", {"ramp", "step"}, "ramp") == "step";
  has_cycles_ = params.has("cycles");
  const std::int64_t cycles = params.integer("cycles", 0);
  if (has_cycles_) {
    if (cycles < 1) {
      params.fail("cycles", "must be >= 1 (or absent to run forever), got " + std::to_string(cycles));
    } else if (period_ns_ > 0 && cycles > static_cast<std::int64_t>(source::kMaxTimeS * 1e9) / period_ns_) {
      params.fail("cycles", "cycles * period_s must not exceed 1e9 s");
    } else {
      end_ns_ = cycles * period_ns_;
    }
  }
  return output_.declare(ctx);
}

StepStatus ZigzagSource::step(const Tick& tick) noexcept {
  std::int64_t tau_ns = tick.time_ns - start_ns_;
  if (tau_ns < 0) {
    output_.write_offset();
    return StepStatus::ok;
  }
  if (has_cycles_) tau_ns = std::min(tau_ns, end_ns_);
  // Half periods in integers: 2 tau / period = k + f exactly at every turning point.
  const std::int64_t twice_tau_ns = 2 * tau_ns;
  const std::int64_t half_periods = twice_tau_ns / period_ns_;
  const double fraction = static_cast<double>(twice_tau_ns - half_periods * period_ns_) /
                          static_cast<double>(period_ns_);
  const double sweep = (half_periods % 2 == 0) ? fraction : 1.0 - fraction;
  const double progress = static_cast<double>(half_periods) + (advance_in_steps_ ? 0.0 : fraction);
  OutputPort& out = output_.port();
  const std::vector<double>& offset = output_.offset();
  for (std::size_t i = 0; i < output_.size(); ++i) {
    out[i] = offset[i] + amplitude_[i] * sweep + advance_[i] * progress;
  }
  return StepStatus::ok;
}

void ZigzagSource::describe(Json& out) const {
  output_.describe(out);
  out["amplitude"] = amplitude_;
  out["advance"] = advance_;
  out["advance_mode"] = advance_in_steps_ ? "step" : "ramp";
  out["period_s"] = static_cast<double>(period_ns_) * 1e-9;
  out["start_s"] = static_cast<double>(start_ns_) * 1e-9;
  if (has_cycles_) {
    out["cycles"] = static_cast<double>(end_ns_ / period_ns_);
    out["end_s"] = static_cast<double>(start_ns_ + end_ns_) * 1e-9;
    std::vector<double> final_value(output_.size());
    const double half_periods = static_cast<double>(2 * (end_ns_ / period_ns_));
    for (std::size_t i = 0; i < output_.size(); ++i) final_value[i] = output_.offset()[i] + advance_[i] * half_periods;
    out["final_value"] = final_value;
  } else {
    out["cycles"] = nullptr;
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"names", "list<text>", nullptr, "output element names, e.g. [x, y]"},
    {"units", "list<text>", nullptr, "SI unit per element, e.g. [m, m]"},
    {"offset", "list<number>", "0 per element", "start point of the path [element unit]"},
    {"amplitude", "list<number>", nullptr,
     "per element: peak of the triangle sweep above offset (0 = no sweep) [element unit]"},
    {"period_s", "number", nullptr, "period of the triangle sweep (out and back) [s], > 0"},
    {"advance", "list<number>", "0 per element",
     "per element: increment per half period [element unit]"},
    {"advance_mode", "text", "ramp",
     "ramp: advance continuously while sweeping; step: add the increment at each turning point"},
    {"cycles", "integer", "none (run forever)", "stop after this many periods and hold"},
    {"start_s", "number", "0", "scheduled start time [s], >= 0; output = offset before"},
};

constexpr PortSpec kPorts[] = {
    {"out", PortDirection::out, "zig-zag path, elements from names/units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::ZigzagSource, "source.zigzag", lode::PluginKind::source, "0.1.0",
            "Zig-zag XY reference path (Kawato Fig. 49): triangle sweep plus advance",
            lode::plugins::kParams, lode::plugins::kPorts)
