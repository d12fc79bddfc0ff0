#include "notch.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

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

using notch::Coefficients;
using notch::Form;
using lode::math::biquad_response;

Status NotchFilter::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  const double rate_hz = ctx.rate_hz();
  const std::size_t count = bank_.configure_channels(ctx);

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

  const Form form = raw ? Form::coefficients : (form_text == "depth" ? Form::depth : Form::eq31);
  std::vector<Coefficients> coefficients(count);
  if (raw) {
    std::optional<std::vector<Coefficients>> given = filter::raw_coefficients(params, raw_values, count);
    if (!given) return Status::error("invalid parameters");
    coefficients = std::move(*given);
  } else {
    f_notch = filter::per_channel(params, "f_notch_hz", f_notch, count);
    k = filter::per_channel(params, "k", k, count);
    zeta = filter::per_channel(params, "zeta", zeta, count);
    for (std::size_t i = 0; i < count; ++i) {
      filter::require_below_nyquist(params, "f_notch_hz", f_notch[i], rate_hz);
      if (!(k[i] > 0.0) || !std::isfinite(k[i])) {
        params.fail("k", (form == Form::eq31 ? std::string("the high-frequency gain") : std::string("the depth")) +
                             " k must be > 0, got " + number_text(k[i]));
      }
      if (!(zeta[i] > 0.0) || !std::isfinite(zeta[i])) params.fail("zeta", "must be > 0, got " + number_text(zeta[i]));
    }
    if (!params.ok()) return Status::error("invalid parameters");
    for (std::size_t i = 0; i < count; ++i) coefficients[i] = notch::design(form, f_notch[i], k[i], zeta[i], rate_hz);
  }
  if (!params.ok()) return Status::error("invalid parameters");
  designed_ = !raw;

  designs_.assign(count, {form, 0.0, 0.0, 0.0});
  for (std::size_t i = 0; i < count && designed_; ++i) designs_[i] = {form, f_notch[i], k[i], zeta[i]};
  return bank_.install(ctx, coefficients, initially_enabled);
}

std::vector<Tunable> NotchFilter::tunables() const {
  std::vector<Tunable> out = BankFilter::tunables();
  if (!designed_) return out;  // raw coefficients: nothing to redesign from
  const double nyquist_hz = 0.5 * bank_.rate_hz();
  out.push_back({"f_notch_hz", "Hz", 0.0, nyquist_hz,
                 false, "notch frequency of every filtered channel, 0 < f < rate/2 (Nyquist refused)"});
  out.push_back({"k", "1", 0.0, 1e300, false,
                 "eq31: high-frequency gain (w0 = w sqrt(k)); depth: gain at f_notch; > 0"});
  out.push_back({"zeta", "1", 0.0, 1e300, false, "damping of the analog denominator (the notch width); > 0"});
  return out;
}

double NotchFilter::tunable_value(std::size_t index) const noexcept {
  // The first filtered channel's design stands for all of them.
  if (designs_.empty()) return 0.0;
  switch (index) {
    case kEnabled: return bank_.enabled_value();
    case kFrequency: return designs_.front().f_notch_hz;
    case kDepth: return designs_.front().k;
    case kDamping: return designs_.front().zeta;
    default: return 0.0;
  }
}

bool NotchFilter::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index == kEnabled) return BankFilter::set_tunable(index, value, why);
  if (!designed_ || index > kDamping) {
    why = designed_ ? "no such parameter" : "raw coefficients: only enabled is tunable";
    return false;
  }
  if (!std::isfinite(value)) {
    why = "the value must be finite";
    return false;
  }
  const double rate_hz = bank_.rate_hz();
  if (index == kFrequency && !(value > 0.0 && value < 0.5 * rate_hz)) {
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
    for (std::size_t slot = 0; slot < designs_.size(); ++slot) {
      notch::ChannelDesign d = designs_[slot];
      (index == kFrequency ? d.f_notch_hz : index == kDepth ? d.k : d.zeta) = value;
      const Coefficients c = notch::design(d.form, d.f_notch_hz, d.k, d.zeta, rate_hz);
      if (pass == 0) {
        const bool finite = std::isfinite(c.b0) && std::isfinite(c.b1) && std::isfinite(c.b2) &&
                            std::isfinite(c.a1) && std::isfinite(c.a2);
        if (!finite || !filter::stable(c)) {
          why = "the redesigned notch is not finite and stable at this value";
          return false;
        }
      } else {
        designs_[slot] = d;
        bank_.retune(slot, c);
      }
    }
  }
  return true;
}

void NotchFilter::describe(Json& out) const {
  const double rate_hz = bank_.rate_hz();
  bank_.describe(
      out,
      [&](std::size_t slot, Json& c) {
        const notch::ChannelDesign& d = designs_[slot];
        c["form"] = notch::to_string(d.form);
        if (d.form != Form::coefficients) {
          c["f_notch_hz"] = d.f_notch_hz;
          c["k"] = d.k;
          c["zeta"] = d.zeta;
          if (d.form == Form::eq31) c["w0_rad_s"] = 2.0 * std::numbers::pi * d.f_notch_hz * std::sqrt(d.k);
          c["discretization"] = "Tustin prewarped at f_notch";
        }
      },
      [&](std::size_t slot, const Coefficients& k, Json& c) {
        const notch::ChannelDesign& d = designs_[slot];
        if (d.form != Form::coefficients) {
          c["gain_at_f_notch_db"] = filter::decibels(biquad_response(k, d.f_notch_hz, rate_hz));
        }
        const auto zeros = lode::math::poly_roots({k.b0, k.b1, k.b2});
        const auto poles = lode::math::poly_roots({1.0, k.a1, k.a2});
        if (!zeros.empty()) {
          // The null lies where the zeros' angle is, if they sit on the unit circle.
          const double angle = std::abs(std::arg(zeros.front()));
          c["zero_radius"] = std::abs(zeros.front());
          c["zero_angle_rad"] = angle;
          c["zero_frequency_hz"] = angle * rate_hz / (2.0 * std::numbers::pi);
        }
        if (!poles.empty()) {
          c["pole_radius"] = std::max(std::abs(poles.front()), std::abs(poles.back()));
          c["pole_angle_rad"] = std::abs(std::arg(poles.front()));
        }
      });
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
