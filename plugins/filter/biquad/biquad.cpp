#include "biquad.hpp"

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
  const double rate_hz = ctx.rate_hz();
  const std::size_t count = bank_.configure_channels(ctx);

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
    std::optional<std::vector<Coefficients>> raw = filter::raw_coefficients(params, raw_values, count);
    if (!raw) return Status::error("invalid parameters");
    coefficients = std::move(*raw);
  } else {
    designed_f = filter::per_channel(params, "f_hz", f_hz, count);
    designed_q = filter::per_channel(params, "q", q, count);
    for (std::size_t i = 0; i < count; ++i) {
      filter::require_below_nyquist(params, "f_hz", designed_f[i], rate_hz);
      if (!(designed_q[i] > 0.0) || !std::isfinite(designed_q[i])) {
        params.fail("q", "the quality factor must be > 0, got " + number_text(designed_q[i]));
      }
    }
    if (!params.ok()) return Status::error("invalid parameters");
    for (std::size_t i = 0; i < count; ++i) {
      coefficients[i] = biquad::design(type, designed_f[i], designed_q[i], rate_hz);
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");

  designs_.assign(count, {});
  for (std::size_t i = 0; i < count; ++i) designs_[i] = {type, designed_f[i], designed_q[i]};
  return bank_.install(ctx, coefficients, initially_enabled);
}

void BiquadFilter::describe(Json& out) const {
  const double rate_hz = bank_.rate_hz();
  bank_.describe(
      out,
      [&](std::size_t slot, Json& c) {
        const biquad::ChannelDesign& d = designs_[slot];
        c["type"] = biquad::to_string(d.type);
        if (d.type != Type::coefficients) {
          c["f_hz"] = d.f_hz;
          c["q"] = d.q;
          c["discretization"] = "Tustin prewarped at f_hz (the RBJ cookbook closed form)";
        }
      },
      [&](std::size_t slot, const Coefficients& k, Json& c) {
        const biquad::ChannelDesign& d = designs_[slot];
        if (d.type != Type::coefficients) c["gain_at_f_db"] = filter::decibels(biquad_response(k, d.f_hz, rate_hz));
        const auto poles = lode::math::poly_roots({1.0, k.a1, k.a2});
        if (!poles.empty()) c["pole_radius"] = std::max(std::abs(poles.front()), std::abs(poles.back()));
      });
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
