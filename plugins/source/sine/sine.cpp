#include "sine.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

Status SineSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  output_.read(params, "centre value");
  const std::size_t size = output_.size();
  amplitude_ = source::read_per_element(params, "amplitude", size);
  frequency_hz_ = source::read_per_element(params, "frequency_hz", size);
  phase_rad_ = source::read_per_element(params, "phase_rad", size, 0.0);
  start_ns_ = source::read_time_ns(params, "start_s", 0.0);
  for (std::size_t i = 0; i < frequency_hz_.size(); ++i) {
    if (frequency_hz_[i] < 0.0) {
      params.fail("frequency_hz", "must be >= 0 Hz, got " + number_text(frequency_hz_[i]) +
                                      " for element " + std::to_string(i));
    }
  }
  // A reference above Nyquist aliases; it is almost certainly a configuration mistake.
  const double nyquist_hz = 0.5 * ctx.rate_hz();
  nyquist_hz_ = nyquist_hz;
  phase_origin_ns_.assign(size, 0);
  cycles_at_origin_.assign(size, 0.0);
  output_.add_tunable({"amplitude", "", "", -1e300, 1e300, "peak amplitude"}, amplitude_);
  output_.add_tunable({"frequency_hz", "", "Hz", 0.0, nyquist_hz, "frequency (phase-continuous), 0 ... rate/2"},
                      frequency_hz_);
  for (std::size_t i = 0; i < frequency_hz_.size(); ++i) {
    if (frequency_hz_[i] > nyquist_hz) {
      params.fail("frequency_hz", "must not exceed the Nyquist frequency " +
                                      number_text(nyquist_hz) + " Hz of this " +
                                      number_text(ctx.rate_hz()) + " Hz block, got " +
                                      number_text(frequency_hz_[i]));
    }
  }
  return output_.declare(ctx);
}

Status SineSource::activate() {
  std::fill(phase_origin_ns_.begin(), phase_origin_ns_.end(), 0);
  std::fill(cycles_at_origin_.begin(), cycles_at_origin_.end(), 0.0);
  last_tau_ns_ = 0;
  return source::ElementSource::activate();  // out = offset
}

StepStatus SineSource::step(const Tick& tick) noexcept {
  if (tick.time_ns < start_ns_) {
    last_tau_ns_ = 0;
    output_.write_offset();
    return StepStatus::ok;
  }
  const std::int64_t tau_ns = tick.time_ns - start_ns_;
  last_tau_ns_ = tau_ns;
  OutputPort& out = output_.port();
  const std::vector<double>& offset = output_.offset();
  for (std::size_t i = 0; i < output_.size(); ++i) {
    // Reduce the cycle count to [0, 1) before multiplying by 2 pi: the phase stays accurate
    // after hours of running (sin of a huge argument loses digits). The time since the phase
    // origin is taken in integer nanoseconds first (no resolution lost on long runs).
    const double since_origin_s = source::elapsed_s(tau_ns, phase_origin_ns_[i]);
    const double cycles = cycles_at_origin_[i] + frequency_hz_[i] * since_origin_s;
    const double fraction = cycles - std::floor(cycles);
    out[i] = offset[i] + amplitude_[i] * std::sin(2.0 * std::numbers::pi * fraction + phase_rad_[i]);
  }
  return StepStatus::ok;
}

bool SineSource::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  std::size_t group = 0, element = 0;
  if (!output_.locate(index, value, group, element, why)) return false;
  if (group == kFrequency) {
    if (!(value >= 0.0 && value <= nyquist_hz_)) {
      why = "frequency_hz must be within [0, rate/2] (above Nyquist the reference aliases)";
      return false;
    }
    // Phase continuity: the phase of the last sample becomes the new origin's phase.
    const double cycles = cycles_at_origin_[element] +
                          frequency_hz_[element] * source::elapsed_s(last_tau_ns_, phase_origin_ns_[element]);
    cycles_at_origin_[element] = cycles - std::floor(cycles);
    phase_origin_ns_[element] = last_tau_ns_;
  }
  output_.store(group, element, value);
  return true;
}

void SineSource::describe(Json& out) const {
  output_.describe(out);
  out["amplitude"] = amplitude_;
  out["frequency_hz"] = frequency_hz_;
  out["phase_rad"] = phase_rad_;
  out["start_s"] = static_cast<double>(start_ns_) * 1e-9;
}

namespace {

constexpr ParamDoc kParams[] = {
    {"names", "list<text>", nullptr, "output element names, e.g. [x, y]"},
    {"units", "list<text>", nullptr, "SI unit per element, e.g. [m, m]"},
    {"offset", "list<number>", "0 per element", "centre value [element unit]"},
    {"amplitude", "list<number>", nullptr, "peak amplitude per element [element unit]"},
    {"frequency_hz", "list<number>", nullptr, "frequency per element [Hz], 0 ... rate/2"},
    {"phase_rad", "list<number>", "0 per element", "phase at start_s per element [rad]"},
    {"start_s", "number", "0", "scheduled start time [s], >= 0; output = offset before"},
};

constexpr PortSpec kPorts[] = {
    {"out", PortDirection::out, "sinusoidal reference, elements from names/units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::SineSource, "source.sine", lode::PluginKind::source, "0.1.0",
            "Sinusoidal reference per element", lode::plugins::kParams, lode::plugins::kPorts)
