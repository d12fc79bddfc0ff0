#include "notch.hpp"

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

namespace notch {

const char* to_string(Form form) {
  switch (form) {
    case Form::eq31: return "eq31";
    case Form::depth: return "depth";
    case Form::coefficients: return "coefficients";
  }
  return "unknown";
}

Coefficients design(Form form, double f_notch_hz, double k, double zeta, double rate_hz) noexcept {
  const double w = 2.0 * std::numbers::pi * f_notch_hz;
  // Analog H(s) = (n0 s^2 + n1 s + n2) / (d0 s^2 + d1 s + d2).
  double n0 = 0.0, n1 = 0.0, n2 = 0.0, d0 = 1.0, d1 = 0.0, d2 = 0.0;
  if (form == Form::depth) {
    n0 = 1.0, n1 = 2.0 * k * zeta * w, n2 = w * w;
    d1 = 2.0 * zeta * w, d2 = w * w;
  } else {
    const double w0 = w * std::sqrt(k);  // eq. 33
    n0 = k, n1 = 0.0, n2 = w0 * w0;      // eq. 31
    d1 = 2.0 * zeta * w0, d2 = w0 * w0;
  }
  // Tustin prewarped at w: s = c (1 - z^-1)/(1 + z^-1), c = w / tan(w T / 2). Multiplying
  // through by (1 + z^-1)^2: s^2 -> c^2 (1 - 2 z^-1 + z^-2), s -> c (1 - z^-2),
  // 1 -> 1 + 2 z^-1 + z^-2 (the closed form for eq31; lode::math::tustin gives the same).
  const double c = w / std::tan(0.5 * w / rate_hz);
  const double c2 = c * c;
  const double b0 = n0 * c2 + n1 * c + n2, b1 = 2.0 * (n2 - n0 * c2), b2 = n0 * c2 - n1 * c + n2;
  const double a0 = d0 * c2 + d1 * c + d2, a1 = 2.0 * (d2 - d0 * c2), a2 = d0 * c2 - d1 * c + d2;
  return {b0 / a0, b1 / a0, b2 / a0, a1 / a0, a2 / a0};
}

}  // namespace notch

namespace {

using notch::Coefficients;
using notch::Form;

/// One number for every filtered channel, or one per filtered channel.
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

/// 20 log10 |h|, floored at -400 dB so an exact null stays a number in describe()'s JSON.
double decibels(std::complex<double> h) { return std::max(20.0 * std::log10(std::abs(h)), -400.0); }

}  // namespace

Status NotchFilter::configure(ConfigureContext& ctx) {
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

  // Which channels are filtered (default all).
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

  const bool raw = params.has("coefficients");
  const bool designed = params.has("f_notch_hz") || params.has("k") || params.has("zeta") || params.has("form");
  std::vector<double> raw_values = params.numbers("coefficients", std::vector<double>{});
  std::vector<double> f_notch = params.numbers("f_notch_hz", std::vector<double>{});
  std::vector<double> k = params.numbers("k", std::vector<double>{0.1});
  std::vector<double> zeta = params.numbers("zeta", std::vector<double>{0.5});
  const std::string form_text = params.choice("form", {"eq31", "depth"}, std::string_view("eq31"));
  const bool initially_enabled = params.flag("enabled", true);
  if (raw && designed) {
    params.fail("coefficients", "give either coefficients [b0, b1, b2, a1, a2] or the design "
                                "(f_notch_hz, k, zeta, form), not both");
  }
  if (!raw && !params.has("f_notch_hz")) {
    params.fail("f_notch_hz", "the notch frequency [Hz] is required (or give raw coefficients)");
  }
  if (!params.ok()) return Status::error("invalid parameters");

  std::vector<Coefficients> coefficients(count);
  designs_.assign(channels_, {});
  if (raw) {
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
      for (int j = 0; j < 5; ++j) {
        if (!std::isfinite(c[j])) params.fail("coefficients", "coefficients must be finite");
      }
    }
  } else {
    f_notch = per_channel(params, "f_notch_hz", f_notch, count);
    k = per_channel(params, "k", k, count);
    zeta = per_channel(params, "zeta", zeta, count);
    const Form form = form_text == "depth" ? Form::depth : Form::eq31;
    for (std::size_t i = 0; i < count; ++i) {
      if (!(f_notch[i] > 0.0 && f_notch[i] < nyquist_hz)) {
        params.fail("f_notch_hz", "must lie in (0, " + number_text(nyquist_hz) + ") Hz (below Nyquist at " +
                                      number_text(rate_hz_) + " Hz), got " + number_text(f_notch[i]));
      }
      if (!(k[i] > 0.0) || !std::isfinite(k[i])) {
        params.fail("k", (form == Form::eq31 ? std::string("the high-frequency gain") : std::string("the depth")) +
                             " k must be > 0, got " + number_text(k[i]));
      }
      if (!(zeta[i] > 0.0) || !std::isfinite(zeta[i])) params.fail("zeta", "must be > 0, got " + number_text(zeta[i]));
    }
    if (!params.ok()) return Status::error("invalid parameters");
    for (std::size_t i = 0; i < count; ++i) coefficients[i] = notch::design(form, f_notch[i], k[i], zeta[i], rate_hz_);
  }
  if (!params.ok()) return Status::error("invalid parameters");
  designed_ = !raw;

  sections_.assign(channels_, {});
  enabled_ = std::make_unique<std::atomic<bool>[]>(channels_);
  filtered_value_.assign(channels_, 0.0);
  for (std::size_t i = 0, used = 0; i < channels_; ++i) {
    notch::ChannelDesign& d = designs_[i];
    d.filtered = filtered[i];
    if (!filtered[i]) {
      enabled_[i].store(false);
      continue;
    }
    d.form = raw ? Form::coefficients : (form_text == "depth" ? Form::depth : Form::eq31);
    if (!raw) {
      d.f_notch_hz = f_notch[used];
      d.k = k[used];
      d.zeta = zeta[used];
    }
    sections_[i].configure(coefficients[used]);
    enabled_[i].store(initially_enabled);
    ++used;
  }
  ctx.declare_output(out_, "out", elements_);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status NotchFilter::activate() {
  if (in_.size() != channels_) {
    return Status::error("filter.notch: the input has " + std::to_string(in_.size()) + " elements, expected " +
                         std::to_string(channels_));
  }
  for (std::size_t i = 0; i < channels_; ++i) {
    sections_[i].reset();
    out_[i] = 0.0;
  }
  return Status::ok();
}

StepStatus NotchFilter::step(const Tick& /*tick*/) noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (!std::isfinite(in_[i])) return fault("non-finite input");
  }
  for (std::size_t i = 0; i < channels_; ++i) {
    const double x = in_[i];
    double y = x;
    if (designs_[i].filtered) {
      // The section runs while bypassed too, so re-enabling starts from a settled state.
      if (!sections_[i].step(x, filtered_value_[i])) return fault("non-finite notch state");
      if (enabled_[i].load(std::memory_order_relaxed)) y = filtered_value_[i];
    }
    out_[i] = y;
  }
  return StepStatus::ok;
}

void NotchFilter::set_enabled(bool enabled) noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (designs_[i].filtered) enabled_[i].store(enabled, std::memory_order_relaxed);
  }
}

bool NotchFilter::set_enabled(std::size_t channel, bool enabled) noexcept {
  if (channel >= channels_ || !designs_[channel].filtered) return false;
  enabled_[channel].store(enabled, std::memory_order_relaxed);
  return true;
}

bool NotchFilter::enabled(std::size_t channel) const noexcept {
  return channel < channels_ && enabled_[channel].load(std::memory_order_relaxed);
}

std::size_t NotchFilter::first_filtered() const noexcept {
  for (std::size_t i = 0; i < channels_; ++i) {
    if (designs_[i].filtered) return i;
  }
  return channels_;
}

std::vector<Tunable> NotchFilter::tunables() const {
  std::vector<Tunable> out;
  out.push_back({"enabled", "bool", 0.0, 1.0, true, "1: filter, 0: bypass (out = in) every filtered channel"});
  if (!designed_) return out;  // raw coefficients: nothing to redesign from
  const double nyquist_hz = 0.5 * rate_hz_;
  out.push_back({"f_notch_hz", "Hz", 0.0, nyquist_hz,
                 false, "notch frequency of every filtered channel, 0 < f < rate/2 (Nyquist refused)"});
  out.push_back({"k", "1", 0.0, 1e300, false,
                 "eq31: high-frequency gain (w0 = w sqrt(k)); depth: gain at f_notch; > 0"});
  out.push_back({"zeta", "1", 0.0, 1e300, false, "damping of the analog denominator (the notch width); > 0"});
  return out;
}

double NotchFilter::tunable_value(std::size_t index) const noexcept {
  const std::size_t first = first_filtered();
  if (first == channels_) return 0.0;
  switch (index) {
    case kEnabled: return enabled(first) ? 1.0 : 0.0;
    case kFrequency: return designs_[first].f_notch_hz;
    case kDepth: return designs_[first].k;
    case kDamping: return designs_[first].zeta;
    default: return 0.0;
  }
}

bool NotchFilter::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index == kEnabled) {
    if (!(value == 0.0 || value == 1.0)) {
      why = "enabled must be 0 or 1";
      return false;
    }
    set_enabled(value == 1.0);
    return true;
  }
  if (!designed_ || index > kDamping) {
    why = designed_ ? "no such parameter" : "raw coefficients: only enabled is tunable";
    return false;
  }
  if (!std::isfinite(value)) {
    why = "the value must be finite";
    return false;
  }
  if (index == kFrequency && !(value > 0.0 && value < 0.5 * rate_hz_)) {
    why = "f_notch_hz must lie strictly between 0 and the Nyquist frequency rate/2";
    return false;
  }
  if (index == kDepth && !(value > 0.0)) {
    why = "k must be > 0";
    return false;
  }
  if (index == kDamping && !(value > 0.0)) {
    why = "zeta must be > 0";
    return false;
  }
  // Design every channel first, apply only if all are finite and stable: all or nothing.
  for (std::size_t pass = 0; pass < 2; ++pass) {
    for (std::size_t i = 0; i < channels_; ++i) {
      notch::ChannelDesign d = designs_[i];
      if (!d.filtered) continue;
      (index == kFrequency ? d.f_notch_hz : index == kDepth ? d.k : d.zeta) = value;
      const Coefficients c = notch::design(d.form, d.f_notch_hz, d.k, d.zeta, rate_hz_);
      if (pass == 0) {
        const bool finite = std::isfinite(c.b0) && std::isfinite(c.b1) && std::isfinite(c.b2) &&
                            std::isfinite(c.a1) && std::isfinite(c.a2);
        if (!finite || !(std::abs(c.a2) < 1.0 && std::abs(c.a1) < 1.0 + c.a2)) {
          why = "the redesigned notch is not finite and stable at this value";
          return false;
        }
      } else {
        designs_[i] = d;
        sections_[i].retune(c);
      }
    }
  }
  return true;
}

void NotchFilter::describe(Json& out) const {
  out["rate_hz"] = rate_hz_;
  out["structure"] = "transposed direct form II per channel; bypassed channels keep filtering in the background";
  Json channels = Json::array();
  for (std::size_t i = 0; i < channels_; ++i) {
    const notch::ChannelDesign& d = designs_[i];
    Json c = Json::object();
    c["name"] = elements_[i].name;
    c["filtered"] = d.filtered;
    if (!d.filtered) {
      channels.push(std::move(c));
      continue;
    }
    c["enabled"] = enabled(i);
    c["form"] = notch::to_string(d.form);
    if (d.form != notch::Form::coefficients) {
      c["f_notch_hz"] = d.f_notch_hz;
      c["k"] = d.k;
      c["zeta"] = d.zeta;
      if (d.form == notch::Form::eq31) c["w0_rad_s"] = 2.0 * std::numbers::pi * d.f_notch_hz * std::sqrt(d.k);
      c["discretization"] = "Tustin prewarped at f_notch";
    }
    const Coefficients& k = sections_[i].coefficients();
    c["b"] = std::vector<double>{k.b0, k.b1, k.b2};
    c["a"] = std::vector<double>{1.0, k.a1, k.a2};
    c["dc_gain"] = std::abs(biquad_response(k, 0.0, rate_hz_));
    c["nyquist_gain"] = std::abs(biquad_response(k, 0.5 * rate_hz_, rate_hz_));
    if (d.form != notch::Form::coefficients) c["gain_at_f_notch_db"] = decibels(biquad_response(k, d.f_notch_hz, rate_hz_));
    const auto zeros = lode::math::poly_roots({k.b0, k.b1, k.b2});
    const auto poles = lode::math::poly_roots({1.0, k.a1, k.a2});
    if (!zeros.empty()) {
      // The null lies where the zeros' angle is, if they sit on the unit circle.
      const double angle = std::abs(std::arg(zeros.front()));
      c["zero_radius"] = std::abs(zeros.front());
      c["zero_angle_rad"] = angle;
      c["zero_frequency_hz"] = angle * rate_hz_ / (2.0 * std::numbers::pi);
    }
    if (!poles.empty()) {
      c["pole_radius"] = std::max(std::abs(poles.front()), std::abs(poles.back()));
      c["pole_angle_rad"] = std::abs(std::arg(poles.front()));
    }
    channels.push(std::move(c));
  }
  out["channels"] = std::move(channels);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"f_notch_hz", "number|list<number>", nullptr,
     "notch frequency per filtered channel (or one for all), 0 < f < rate/2; required unless coefficients"},
    {"k", "number|list<number>", "0.1",
     "eq31: high-frequency gain (w0 = w sqrt(k), eq. 33; 0.1 = -20 dB); depth: gain at f_notch; > 0"},
    {"zeta", "number|list<number>", "0.5", "damping of the analog denominator; > 0"},
    {"form", "text", "eq31",
     "eq31: H(s) = (k s^2 + w0^2)/(s^2 + 2 zeta w0 s + w0^2) (paper eq. 31, null at f_notch); "
     "depth: H(s) = (s^2 + 2 k zeta w s + w^2)/(s^2 + 2 zeta w s + w^2)"},
    {"coefficients", "list<number>", "none",
     "raw [b0, b1, b2, a1, a2] (a0 = 1), 5 for every channel or 5 per filtered channel, e.g. eq. 34 "
     "[0.09318, -0.1733, 0.09318, -1.792, 0.8047]; excludes the design keys"},
    {"channels", "list<text>", "all", "names of the input elements to filter; the others pass through"},
    {"enabled", "bool", "true", "start filtering (false: out = in until set_enabled(true))"},
};

constexpr PortSpec kPorts[] = {
    {"in", PortDirection::in, "n signals, any names and units (e.g. the planar pose x, y, phi)"},
    {"out", PortDirection::out, "the n signals, notched where filtered and enabled; same names and units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::NotchFilter, "filter.notch", lode::PluginKind::filter, "0.1.0",
            "Per-channel second-order notch by prewarped Tustin (Silva-Rivas & Kim eq. 31-34) or raw coefficients",
            lode::plugins::kParams, lode::plugins::kPorts)
