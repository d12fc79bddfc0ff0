#include "biquad.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <string>

#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace biquad {

const char* to_string(Type type) {
  switch (type) {
    case Type::lowpass: return "lowpass";
    case Type::highpass: return "highpass";
    case Type::bandpass: return "bandpass";
    case Type::notch: return "notch";
    case Type::coefficients: return "coefficients";
  }
  return "unknown";
}

Coefficients design(Type type, double f_hz, double q, double rate_hz) {
  const double w0 = 2.0 * std::numbers::pi * f_hz;
  const std::vector<double> den{1.0, w0 / q, w0 * w0};
  std::vector<double> num;
  switch (type) {
    case Type::lowpass: num = {0.0, 0.0, w0 * w0}; break;
    case Type::highpass: num = {1.0, 0.0, 0.0}; break;
    case Type::bandpass: num = {0.0, w0 / q, 0.0}; break;
    case Type::notch: num = {1.0, 0.0, w0 * w0}; break;
    case Type::coefficients: return {};
  }
  const lode::math::TransferFunction d = lode::math::tustin({num, den}, 1.0 / rate_hz, w0);
  return {d.num[0], d.num[1], d.num[2], d.den[1], d.den[2]};
}

}  // namespace biquad

namespace {

using biquad::Coefficients;
using biquad::Type;

std::vector<double> per_channel(Params& params, std::string_view key, std::vector<double> values, std::size_t n) {
  if (values.size() == 1 && n > 1) values.assign(n, values.front());
  if (values.size() != n) {
    params.fail(key, "expected one number or " + std::to_string(n) + " (one per filtered channel), got " +
                         std::to_string(values.size()));
    values.assign(n, 0.0);
  }
  return values;
}

using lode::math::biquad_response;

Type type_from(const std::string& text) {
  if (text == "highpass") return Type::highpass;
  if (text == "bandpass") return Type::bandpass;
  if (text == "notch") return Type::notch;
  if (text == "coefficients") return Type::coefficients;
  return Type::lowpass;
}

}  // namespace

Status BiquadFilter::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  rate_hz_ = ctx.rate_hz();
  const double nyquist_hz = 0.5 * rate_hz_;

  ctx.declare_input(in_, "in", {}, true);
  const Elements* source = ctx.input_source("in");
  if (source == nullptr || source->empty()) {
    params.fail("inputs", "the in input must be connected to a configured block's output: its elements name "
                          "and size the channels");
  } else {
    elements_ = *source;
  }
  channels_ = elements_.size();

  std::vector<std::string> selected = params.texts("channels", {});
  std::vector<bool> filtered(channels_, !params.has("channels"));
  for (const std::string& name : selected) {
    const auto found =
        std::find_if(elements_.begin(), elements_.end(), [&](const Element& e) { return e.name == name; });
    if (found == elements_.end()) {
      params.fail("channels", "'" + name + "' is not an element of the input");
    } else {
      filtered[static_cast<std::size_t>(found - elements_.begin())] = true;
    }
  }
  const auto count = static_cast<std::size_t>(std::count(filtered.begin(), filtered.end(), true));

  const Type type = type_from(
      params.choice("type", {"lowpass", "highpass", "bandpass", "notch", "coefficients"}));
  std::vector<double> raw_values = params.numbers("coefficients", std::vector<double>{});
  std::vector<double> f_hz = params.numbers("f_hz", std::vector<double>{});
  std::vector<double> q = params.numbers("q", std::vector<double>{std::numbers::sqrt2 / 2.0});
  const bool initially_enabled = params.flag("enabled", true);
  if (type == Type::coefficients) {
    if (!params.has("coefficients")) params.fail("coefficients", "type: coefficients needs [b0, b1, b2, a1, a2]");
    if (params.has("f_hz") || params.has("q")) params.fail("type", "f_hz and q apply to the designed types only");
  } else {
    if (params.has("coefficients")) params.fail("coefficients", "raw coefficients need type: coefficients");
    if (!params.has("f_hz")) params.fail("f_hz", "the corner/centre frequency [Hz] is required");
  }
  if (!params.ok()) return Status::error("invalid parameters");

  std::vector<Coefficients> coefficients(count);
  std::vector<double> designed_f(count, 0.0);
  std::vector<double> designed_q(count, 0.0);
  if (type == Type::coefficients) {
    if (raw_values.size() == 5) {
      for (std::size_t i = 1; i < count; ++i) raw_values.insert(raw_values.end(), raw_values.begin(), raw_values.begin() + 5);
    }
    if (raw_values.size() != 5 * count) {
      params.fail("coefficients", "expected 5 numbers [b0, b1, b2, a1, a2] or 5 per filtered channel (" +
                                      std::to_string(5 * count) + "), got " + std::to_string(raw_values.size()));
      return Status::error("invalid parameters");
    }
    for (std::size_t i = 0; i < count; ++i) {
      const double* c = &raw_values[5 * i];
      coefficients[i] = {c[0], c[1], c[2], c[3], c[4]};
      // Stable iff both roots of z^2 + a1 z + a2 lie inside the unit circle (Jury: |a2| < 1, |a1| < 1 + a2).
      if (!(std::abs(c[4]) < 1.0 && std::abs(c[3]) < 1.0 + c[4])) {
        params.fail("coefficients", "unstable denominator 1 + " + number_text(c[3]) + " z^-1 + " + number_text(c[4]) +
                                        " z^-2 (a pole on or outside the unit circle)");
      }
    }
  } else {
    designed_f = per_channel(params, "f_hz", f_hz, count);
    designed_q = per_channel(params, "q", q, count);
    for (std::size_t i = 0; i < count; ++i) {
      if (!(designed_f[i] > 0.0 && designed_f[i] < nyquist_hz)) {
        params.fail("f_hz", "must lie in (0, " + number_text(nyquist_hz) + ") Hz (below Nyquist at " +
                                number_text(rate_hz_) + " Hz), got " + number_text(designed_f[i]));
      }
      if (!(designed_q[i] > 0.0) || !std::isfinite(designed_q[i])) {
        params.fail("q", "the quality factor must be > 0, got " + number_text(designed_q[i]));
      }
    }
    if (!params.ok()) return Status::error("invalid parameters");
    for (std::size_t i = 0; i < count; ++i) {
      coefficients[i] = biquad::design(type, designed_f[i], designed_q[i], rate_hz_);
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");

  designs_.assign(channels_, {});
  sections_.assign(channels_, {});
  enabled_ = std::make_unique<std::atomic<bool>[]>(channels_);
  filtered_value_.assign(channels_, 0.0);
  for (std::size_t i = 0, used = 0; i < channels_; ++i) {
    biquad::ChannelDesign& d = designs_[i];
    d.filtered = filtered[i];
    if (!filtered[i]) {
      enabled_[i].store(false);
      continue;
    }
    d.type = type;
    d.f_hz = designed_f[used];
    d.q = designed_q[used];
    sections_[i].configure(coefficients[used]);
    enabled_[i].store(initially_enabled);
    ++used;
  }
  ctx.declare_output(out_, "out", elements_);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status BiquadFilter::activate() {
  if (in_.size() != channels_) {
    return Status::error("filter.biquad: the input has " + std::to_string(in_.size()) + " elements, expected " +
                         std::to_string(channels_));
  }
  for (std::size_t i = 0; i < channels_; ++i) {
    sections_[i].reset();
    out_[i] = 0.0;
  }
  return Status::ok();
}

StepStatus BiquadFilter::step(const Tick& /*tick*/) noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (!std::isfinite(in_[i])) return fault("non-finite input");
  }
  for (std::size_t i = 0; i < channels_; ++i) {
    const double x = in_[i];
    double y = x;
    if (designs_[i].filtered) {
      // The section runs while bypassed too, so re-enabling starts from a settled state.
      if (!sections_[i].step(x, filtered_value_[i])) return fault("non-finite biquad state");
      if (enabled_[i].load(std::memory_order_relaxed)) y = filtered_value_[i];
    }
    out_[i] = y;
  }
  return StepStatus::ok;
}

void BiquadFilter::set_enabled(bool enabled) noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (designs_[i].filtered) enabled_[i].store(enabled, std::memory_order_relaxed);
  }
}

bool BiquadFilter::set_enabled(std::size_t channel, bool enabled) noexcept {
  if (channel >= channels_ || !designs_[channel].filtered) return false;
  enabled_[channel].store(enabled, std::memory_order_relaxed);
  return true;
}

bool BiquadFilter::enabled(std::size_t channel) const noexcept {
  return channel < channels_ && enabled_[channel].load(std::memory_order_relaxed);
}

std::vector<Tunable> BiquadFilter::tunables() const {
  return {{"enabled", "bool", 0.0, 1.0, true, "1: filter, 0: bypass (out = in) every filtered channel"}};
}

double BiquadFilter::tunable_value(std::size_t index) const noexcept {
  if (index != 0) return 0.0;
  for (std::size_t i = 0; i < channels_; ++i) {
    if (designs_[i].filtered) return enabled(i) ? 1.0 : 0.0;
  }
  return 0.0;
}

bool BiquadFilter::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index != 0) {
    why = "no such parameter";
    return false;
  }
  if (!(value == 0.0 || value == 1.0)) {
    why = "enabled must be 0 or 1";
    return false;
  }
  // The sections keep running while bypassed, so switching either way has no stale state.
  set_enabled(value == 1.0);
  return true;
}

void BiquadFilter::describe(Json& out) const {
  out["rate_hz"] = rate_hz_;
  out["structure"] = "transposed direct form II per channel; bypassed channels keep filtering in the background";
  Json channels = Json::array();
  for (std::size_t i = 0; i < channels_; ++i) {
    const biquad::ChannelDesign& d = designs_[i];
    Json c = Json::object();
    c["name"] = elements_[i].name;
    c["filtered"] = d.filtered;
    if (!d.filtered) {
      channels.push(std::move(c));
      continue;
    }
    c["enabled"] = enabled(i);
    c["type"] = biquad::to_string(d.type);
    if (d.type != Type::coefficients) {
      c["f_hz"] = d.f_hz;
      c["q"] = d.q;
      c["discretization"] = "Tustin prewarped at f_hz (the RBJ cookbook closed form)";
    }
    const Coefficients& k = sections_[i].coefficients();
    c["b"] = std::vector<double>{k.b0, k.b1, k.b2};
    c["a"] = std::vector<double>{1.0, k.a1, k.a2};
    c["dc_gain"] = std::abs(biquad_response(k, 0.0, rate_hz_));
    c["nyquist_gain"] = std::abs(biquad_response(k, 0.5 * rate_hz_, rate_hz_));
    if (d.type != Type::coefficients) {
      // Floored at -400 dB so a notch's exact null stays a number in the JSON.
      c["gain_at_f_db"] = std::max(20.0 * std::log10(std::abs(biquad_response(k, d.f_hz, rate_hz_))), -400.0);
    }
    const auto poles = lode::math::poly_roots({1.0, k.a1, k.a2});
    if (!poles.empty()) c["pole_radius"] = std::max(std::abs(poles.front()), std::abs(poles.back()));
    channels.push(std::move(c));
  }
  out["channels"] = std::move(channels);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"type", "text", nullptr, "lowpass | highpass | bandpass | notch (RBJ cookbook, prewarped Tustin) | coefficients"},
    {"f_hz", "number|list<number>", nullptr,
     "corner (lowpass/highpass) or centre (bandpass/notch) frequency per filtered channel (or one for all), "
     "0 < f < rate/2; designed types only"},
    {"q", "number|list<number>", "0.7071", "quality factor Q of the analog prototype (0.7071: Butterworth); > 0"},
    {"coefficients", "list<number>", "none",
     "type: coefficients: [b0, b1, b2, a1, a2] (a0 = 1), 5 for every channel or 5 per filtered channel"},
    {"channels", "list<text>", "all", "names of the input elements to filter; the others pass through"},
    {"enabled", "bool", "true", "start filtering (false: out = in until set_enabled(true))"},
};

constexpr PortSpec kPorts[] = {
    {"in", PortDirection::in, "n signals, any names and units"},
    {"out", PortDirection::out, "the n signals, filtered where selected and enabled; same names and units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::BiquadFilter, "filter.biquad", lode::PluginKind::filter, "0.1.0",
            "Per-channel biquad: RBJ low/high/band-pass or notch by prewarped Tustin, or raw coefficients",
            lode::plugins::kParams, lode::plugins::kPorts)
