#include "biquad_bank.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins::filter {

std::vector<double> per_channel(Params& params, std::string_view key, std::vector<double> values, std::size_t count) {
  if (values.size() == 1 && count > 1) values.assign(count, values.front());
  if (values.size() != count) {
    params.fail(key, "expected one number or " + std::to_string(count) + " (one per filtered channel), got " +
                         std::to_string(values.size()));
    values.assign(count, 0.0);
  }
  return values;
}

std::optional<std::vector<Coefficients>> raw_coefficients(Params& params, std::vector<double> values, std::size_t count) {
  if (values.size() == 5) {
    for (std::size_t i = 1; i < count; ++i) values.insert(values.end(), values.begin(), values.begin() + 5);
  }
  if (values.size() != 5 * count) {
    params.fail("coefficients", "expected 5 numbers [b0, b1, b2, a1, a2] or 5 per filtered channel (" +
                                    std::to_string(5 * count) + "), got " + std::to_string(values.size()));
    return std::nullopt;
  }
  std::vector<Coefficients> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double* c = &values[5 * i];
    out[i] = {c[0], c[1], c[2], c[3], c[4]};
    if (!stable(out[i])) {
      params.fail("coefficients", "unstable denominator 1 + " + number_text(c[3]) + " z^-1 + " + number_text(c[4]) +
                                      " z^-2 (a pole on or outside the unit circle)");
    }
    for (int j = 0; j < 5; ++j) {
      if (!std::isfinite(c[j])) params.fail("coefficients", "coefficients must be finite");
    }
  }
  return out;
}

bool stable(const Coefficients& c) noexcept { return std::abs(c.a2) < 1.0 && std::abs(c.a1) < 1.0 + c.a2; }

void require_below_nyquist(Params& params, std::string_view key, double f_hz, double rate_hz) {
  const double nyquist_hz = 0.5 * rate_hz;
  if (!(f_hz > 0.0 && f_hz < nyquist_hz)) {
    params.fail(key, "must lie in (0, " + number_text(nyquist_hz) + ") Hz (below Nyquist at " + number_text(rate_hz) +
                         " Hz), got " + number_text(f_hz));
  }
}

double decibels(std::complex<double> h) { return std::max(20.0 * std::log10(std::abs(h)), -400.0); }

std::size_t BiquadBank::configure_channels(ConfigureContext& ctx) {
  Params& params = ctx.params();
  rate_hz_ = ctx.rate_hz();
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
  slot_.assign(channels_, kPassThrough);
  std::size_t count = 0;
  for (std::size_t i = 0; i < channels_; ++i) {
    if (filtered[i]) slot_[i] = count++;
  }
  return count;
}

Status BiquadBank::install(ConfigureContext& ctx, const std::vector<Coefficients>& coefficients, bool enabled) {
  sections_.assign(coefficients.size(), {});
  filtered_value_.assign(coefficients.size(), 0.0);
  enabled_ = std::make_unique<std::atomic<bool>[]>(channels_);
  for (std::size_t i = 0; i < channels_; ++i) {
    const std::size_t s = slot_[i];
    if (s != kPassThrough) sections_[s].configure(coefficients[s]);
    enabled_[i].store(s != kPassThrough && enabled);
  }
  ctx.declare_output(out_, "out", elements_);
  return ctx.params().ok() ? Status::ok() : Status::error("invalid parameters");
}

Status BiquadBank::activate() {
  if (in_.size() != channels_) {
    return Status::error(std::string(plugin_) + ": the input has " + std::to_string(in_.size()) +
                         " elements, expected " + std::to_string(channels_));
  }
  for (lode::math::BiquadSection& section : sections_) section.reset();
  for (std::size_t i = 0; i < channels_; ++i) out_[i] = 0.0;
  return Status::ok();
}

const char* BiquadBank::step() noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (!std::isfinite(in_[i])) return "non-finite input";
  }
  for (std::size_t i = 0; i < channels_; ++i) {
    const double x = in_[i];
    double y = x;
    if (const std::size_t s = slot_[i]; s != kPassThrough) {
      // The section runs while bypassed too, so re-enabling starts from a settled state.
      if (!sections_[s].step(x, filtered_value_[s])) return state_fault_;
      if (enabled_[i].load(std::memory_order_relaxed)) y = filtered_value_[s];
    }
    out_[i] = y;
  }
  return nullptr;
}

void BiquadBank::set_enabled(bool enabled) noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (slot_[i] != kPassThrough) enabled_[i].store(enabled, std::memory_order_relaxed);
  }
}

bool BiquadBank::set_enabled(std::size_t channel, bool enabled) noexcept {
  if (channel >= channels_ || slot_[channel] == kPassThrough) return false;
  enabled_[channel].store(enabled, std::memory_order_relaxed);
  return true;
}

bool BiquadBank::enabled(std::size_t channel) const noexcept {
  return channel < channels_ && enabled_[channel].load(std::memory_order_relaxed);
}

Tunable BiquadBank::enabled_tunable() {
  return {"enabled", "bool", 0.0, 1.0, true, "1: filter, 0: bypass (out = in) every filtered channel"};
}

double BiquadBank::enabled_value() const noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (slot_[i] != kPassThrough) return enabled(i) ? 1.0 : 0.0;
  }
  return 0.0;
}

bool BiquadBank::set_enabled_tunable(double value, const char*& why) noexcept {
  if (!(value == 0.0 || value == 1.0)) {
    why = "enabled must be 0 or 1";
    return false;
  }
  // The sections keep running while bypassed, so switching either way has no stale state.
  set_enabled(value == 1.0);
  return true;
}

void BiquadBank::describe(
    Json& out, const std::function<void(std::size_t slot, Json& channel)>& design,
    const std::function<void(std::size_t slot, const Coefficients& k, Json& channel)>& response) const {
  out["rate_hz"] = rate_hz_;
  out["structure"] = "transposed direct form II per channel; bypassed channels keep filtering in the background";
  Json channels = Json::array();
  for (std::size_t i = 0; i < channels_; ++i) {
    const std::size_t s = slot_[i];
    Json c = Json::object();
    c["name"] = elements_[i].name;
    c["filtered"] = s != kPassThrough;
    if (s == kPassThrough) {
      channels.push(std::move(c));
      continue;
    }
    c["enabled"] = enabled(i);
    design(s, c);
    const Coefficients& k = sections_[s].coefficients();
    c["b"] = std::vector<double>{k.b0, k.b1, k.b2};
    c["a"] = std::vector<double>{1.0, k.a1, k.a2};
    c["dc_gain"] = std::abs(lode::math::biquad_response(k, 0.0, rate_hz_));
    c["nyquist_gain"] = std::abs(lode::math::biquad_response(k, 0.5 * rate_hz_, rate_hz_));
    response(s, k, c);
    channels.push(std::move(c));
  }
  out["channels"] = std::move(channels);
}

}  // namespace lode::plugins::filter
