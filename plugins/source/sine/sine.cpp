#include "sine.hpp"

#include <cmath>
#include <numbers>

#include "../common/source_elements.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

Status SineSource::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  source::SourceElements elements = source::read_source_elements(params);
  size_ = elements.size();
  offset_ = elements.offset;
  amplitude_ = source::read_per_element(params, "amplitude", size_);
  frequency_hz_ = source::read_per_element(params, "frequency_hz", size_);
  phase_rad_ = source::read_per_element(params, "phase_rad", size_, 0.0);
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
  elements_ = elements.elements;
  phase_origin_ns_.assign(size_, 0);
  cycles_at_origin_.assign(size_, 0.0);
  tunables_.add({"offset", "", "", -1e300, 1e300, "centre value"});
  tunables_.add({"amplitude", "", "", -1e300, 1e300, "peak amplitude"});
  tunables_.add({"frequency_hz", "", "Hz", 0.0, nyquist_hz, "frequency (phase-continuous), 0 ... rate/2"});
  for (std::size_t i = 0; i < frequency_hz_.size(); ++i) {
    if (frequency_hz_[i] > nyquist_hz) {
      params.fail("frequency_hz", "must not exceed the Nyquist frequency " +
                                      number_text(nyquist_hz) + " Hz of this " +
                                      number_text(ctx.rate_hz()) + " Hz block, got " +
                                      number_text(frequency_hz_[i]));
    }
  }

  ctx.declare_output(out_, "out", elements.elements);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status SineSource::activate() {
  for (std::size_t i = 0; i < size_; ++i) {
    out_[i] = offset_[i];
    phase_origin_ns_[i] = 0;
    cycles_at_origin_[i] = 0.0;
  }
  last_tau_ns_ = 0;
  return Status::ok();
}

StepStatus SineSource::step(const Tick& tick) noexcept {
  if (tick.time_ns < start_ns_) {
    last_tau_ns_ = 0;
    for (std::size_t i = 0; i < size_; ++i) out_[i] = offset_[i];
    return StepStatus::ok;
  }
  const std::int64_t tau_ns = tick.time_ns - start_ns_;
  last_tau_ns_ = tau_ns;
  for (std::size_t i = 0; i < size_; ++i) {
    // Reduce the cycle count to [0, 1) before multiplying by 2 pi: the phase stays accurate
    // after hours of running (sin of a huge argument loses digits). The time since the phase
    // origin is taken in integer nanoseconds first (no resolution lost on long runs).
    const double since_origin_s = source::elapsed_s(tau_ns, phase_origin_ns_[i]);
    const double cycles = cycles_at_origin_[i] + frequency_hz_[i] * since_origin_s;
    const double fraction = cycles - std::floor(cycles);
    out_[i] = offset_[i] +
              amplitude_[i] * std::sin(2.0 * std::numbers::pi * fraction + phase_rad_[i]);
  }
  return StepStatus::ok;
}

std::vector<Tunable> SineSource::tunables() const { return tunables_.list(elements_); }

double SineSource::tunable_value(std::size_t index) const noexcept {
  std::size_t group = 0, element = 0;
  if (!tunables_.locate(index, size_, group, element)) return 0.0;
  switch (group) {
    case 0: return offset_[element];
    case 1: return amplitude_[element];
    default: return frequency_hz_[element];
  }
}

bool SineSource::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  std::size_t group = 0, element = 0;
  if (!tunables_.locate(index, size_, group, element)) {
    why = "no such parameter";
    return false;
  }
  if (!source::accept_finite(value, why)) return false;
  switch (group) {
    case 0: offset_[element] = value; return true;
    case 1: amplitude_[element] = value; return true;
    default: break;
  }
  if (!(value >= 0.0 && value <= nyquist_hz_)) {
    why = "frequency_hz must be within [0, rate/2] (above Nyquist the reference aliases)";
    return false;
  }
  // Phase continuity: the phase of the last sample becomes the new origin's phase.
  const double cycles = cycles_at_origin_[element] +
                        frequency_hz_[element] * source::elapsed_s(last_tau_ns_, phase_origin_ns_[element]);
  cycles_at_origin_[element] = cycles - std::floor(cycles);
  phase_origin_ns_[element] = last_tau_ns_;
  frequency_hz_[element] = value;
  return true;
}

void SineSource::describe(Json& out) const {
  out["elements"] = static_cast<int>(size_);
  out["offset"] = offset_;
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
