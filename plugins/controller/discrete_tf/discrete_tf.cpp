#include "discrete_tf.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <set>
#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace discrete_tf {

namespace {

std::string number_text(double value) { return lode::number_text(value, 10); }

/// Roots closer than this to s = 0 [rad/s] are treated as lying at the origin (integrators,
/// differentiators): they map to z = 1 exactly and take part in the gain matching.
constexpr double kOriginTolerance = 1e-12;

bool at_origin(double root) { return std::abs(root) <= kOriginTolerance; }

Status check_s_form(const std::vector<double>& zeros_s, const std::vector<double>& poles_s, double gain) {
  if (poles_s.size() > kMaxOrder) {
    return Status::error("at most " + std::to_string(kMaxOrder) + " poles, got " + std::to_string(poles_s.size()));
  }
  if (zeros_s.size() > poles_s.size()) {
    return Status::error("improper D(s): " + std::to_string(zeros_s.size()) + " zeros but only " +
                         std::to_string(poles_s.size()) + " poles (a causal D(z) needs zeros <= poles)");
  }
  if (gain == 0.0) return Status::error("gain must not be 0");
  return Status::ok();
}

}  // namespace

const char* to_string(Method method) {
  switch (method) {
    case Method::matched: return "matched";
    case Method::tustin: return "tustin";
    case Method::direct: return "direct";
  }
  return "unknown";
}

double Design::gain_z() const {
  for (double c : num) {
    if (c != 0.0) return c;
  }
  return 0.0;
}

std::vector<double> Design::monic_numerator() const {
  const double k = gain_z();
  std::vector<double> out;
  for (double c : num) {
    if (out.empty() && c == 0.0) continue;
    out.push_back(c / k);
  }
  return out;
}

std::complex<double> Design::evaluate(std::complex<double> z) const {
  std::complex<double> n = 0.0;
  std::complex<double> d = 0.0;
  for (double c : num) n = n * z + c;
  for (double c : den) d = d * z + c;
  return n / d;
}

namespace {

lode::math::Zpk zpk(const std::vector<double>& zeros_s, const std::vector<double>& poles_s, double gain) {
  lode::math::Zpk out;
  out.gain = gain;
  for (double z : zeros_s) out.zeros.emplace_back(z, 0.0);
  for (double p : poles_s) out.poles.emplace_back(p, 0.0);
  return out;
}

bool usable(const std::vector<double>& coefficients) {
  return std::all_of(coefficients.begin(), coefficients.end(), [](double c) { return std::isfinite(c); }) &&
         std::any_of(coefficients.begin(), coefficients.end(), [](double c) { return c != 0.0; });
}

}  // namespace

Expected<Design> matched_pole_zero(const std::vector<double>& zeros_s, const std::vector<double>& poles_s,
                                   double gain, double period_s) {
  if (Status s = check_s_form(zeros_s, poles_s, gain); !s) return s;
  Design d;
  d.method = Method::matched;
  d.zeros_s = zeros_s;
  d.poles_s = poles_s;
  d.gain_s = gain;
  // z = e^{sT}, zeros at infinity -> z = -1, gain matched at low frequency: lode::math.
  const lode::math::TransferFunction tf = lode::math::matched_pole_zero(zpk(zeros_s, poles_s, gain), period_s);
  if (!usable(tf.num)) {
    return Status::error("the matched gain is not finite (a pole or zero too close to the origin?)");
  }
  d.num = tf.num;
  d.den = tf.den;
  // For describe(): k = (poles at 0) - (zeros at 0) and lim s^k D(s), which the gain matches.
  d.low_frequency_gain = gain;
  for (double z : zeros_s) {
    if (at_origin(z)) {
      --d.origin_order;
    } else {
      d.low_frequency_gain *= -z;
    }
  }
  for (double p : poles_s) {
    if (at_origin(p)) {
      ++d.origin_order;
    } else {
      d.low_frequency_gain /= -p;
    }
  }
  return d;
}

Expected<Design> tustin(const std::vector<double>& zeros_s, const std::vector<double>& poles_s, double gain,
                        double period_s, double prewarp_hz) {
  if (Status s = check_s_form(zeros_s, poles_s, gain); !s) return s;
  const double nyquist_hz = 0.5 / period_s;
  if (prewarp_hz < 0.0 || prewarp_hz >= nyquist_hz) {
    return Status::error("prewarp_hz must lie in (0, " + number_text(nyquist_hz) + ") Hz (below Nyquist), got " +
                         number_text(prewarp_hz));
  }
  Design d;
  d.method = Method::tustin;
  d.zeros_s = zeros_s;
  d.poles_s = poles_s;
  d.gain_s = gain;
  d.prewarp_hz = prewarp_hz;

  // s = c (z-1)/(z+1) maps a root at s = c to z = infinity: refuse it before lode::math::tustin.
  const double w = 2.0 * std::numbers::pi * prewarp_hz;
  const double c = prewarp_hz > 0.0 ? w / std::tan(0.5 * w * period_s) : 2.0 / period_s;
  for (double z : zeros_s) {
    if (std::abs(c - z) <= 1e-12 * c) return Status::error("a zero at s = c = " + number_text(c) + " maps to z = infinity");
  }
  for (double p : poles_s) {
    if (std::abs(c - p) <= 1e-12 * c) return Status::error("a pole at s = c = " + number_text(c) + " maps to z = infinity");
  }
  const lode::math::TransferFunction tf = lode::math::tustin(
      zpk(zeros_s, poles_s, gain), period_s, prewarp_hz > 0.0 ? std::optional<double>(w) : std::nullopt);
  d.num = tf.num;
  d.den = tf.den;
  return d;
}

Expected<Design> direct(const std::vector<double>& num_z, const std::vector<double>& den_z) {
  if (den_z.empty() || den_z.front() == 0.0) {
    return Status::error("den_z must start with a nonzero coefficient of the highest power of z");
  }
  if (den_z.size() > kMaxOrder + 1) {
    return Status::error("order at most " + std::to_string(kMaxOrder) + ", den_z has " +
                         std::to_string(den_z.size()) + " coefficients");
  }
  if (num_z.size() > den_z.size()) {
    return Status::error("num_z has a higher degree than den_z: the controller would need future errors");
  }
  if (std::all_of(num_z.begin(), num_z.end(), [](double c) { return c == 0.0; })) {
    return Status::error("num_z is all zero");
  }
  Design d;
  d.method = Method::direct;
  d.den = den_z;
  d.num.assign(den_z.size() - num_z.size(), 0.0);  // pad: lower degree = pure delay
  d.num.insert(d.num.end(), num_z.begin(), num_z.end());
  const double lead = den_z.front();
  for (double& c : d.num) c /= lead;
  for (double& c : d.den) c /= lead;
  return d;
}

void Section::configure(const Design& design, double limit) {
  order_ = design.order();
  limit_ = limit;
  b_.fill(0.0);
  a_.fill(0.0);
  for (std::size_t i = 0; i <= order_; ++i) {
    b_[i] = design.num[i];
    a_[i] = design.den[i];
  }
  reset();
}

bool Section::step(double error, double& output) noexcept {
  if (!std::isfinite(error)) return false;
  const double linear = b_[0] * error + (order_ > 0 ? state_[0] : 0.0);
  if (!std::isfinite(linear)) return false;

  // Transposed direct form II: s_i <- b_{i+1} e - a_{i+1} u + s_{i+1}.
  std::array<double, kMaxOrder> next{};
  for (std::size_t i = 0; i < order_; ++i) {
    next[i] = b_[i + 1] * error - a_[i + 1] * linear + (i + 1 < order_ ? state_[i + 1] : 0.0);
    if (!std::isfinite(next[i])) return false;
  }

  output = linear;
  saturated_ = limit_ > 0.0 && std::abs(linear) > limit_;
  if (saturated_) {
    const double direction = linear > 0.0 ? 1.0 : -1.0;
    output = direction * limit_;
    // Conditional integration: s0 is the state's contribution to the next output; do not
    // let it grow further in the direction of saturation (an integrator would wind up).
    if (order_ > 0 && (next[0] - state_[0]) * direction > 0.0) return true;
  }
  for (std::size_t i = 0; i < order_; ++i) state_[i] = next[i];
  return true;
}

}  // namespace discrete_tf

namespace {

using discrete_tf::Design;

/// One axis map: {zeros_s, poles_s, gain, discretization, prewarp_hz} or {num_z, den_z}.
Expected<Design> read_axis(Params& axis, double period_s) {
  const bool s_form = axis.has("zeros_s") || axis.has("poles_s") || axis.has("gain") ||
                      axis.has("discretization") || axis.has("prewarp_hz");
  const bool z_form = axis.has("num_z") || axis.has("den_z");
  if (s_form && z_form) {
    axis.fail("give either {zeros_s, poles_s, gain, discretization} or {num_z, den_z}, not both");
    return Status::error("invalid axis");
  }
  if (z_form) {
    const std::vector<double> num = axis.numbers("num_z");
    const std::vector<double> den = axis.numbers("den_z");
    if (!axis.ok()) return Status::error("invalid axis");
    Expected<Design> d = discrete_tf::direct(num, den);
    if (!d) axis.fail("den_z", d.error());
    return d;
  }
  const std::vector<double> zeros = axis.numbers("zeros_s", std::vector<double>{});
  const std::vector<double> poles = axis.numbers("poles_s", std::vector<double>{});
  const double gain = axis.number("gain");
  const std::string method = axis.choice("discretization", {"matched", "tustin"}, std::string_view("matched"));
  const double prewarp_hz = axis.number("prewarp_hz", 0.0);
  if (axis.has("prewarp_hz") && method != "tustin") {
    axis.fail("prewarp_hz", "prewarp_hz applies to discretization: tustin only");
  }
  if (axis.has("prewarp_hz") && !(prewarp_hz > 0.0)) {
    axis.fail("prewarp_hz", "must be > 0 Hz, got " + number_text(prewarp_hz));
  }
  if (!axis.ok()) return Status::error("invalid axis");
  Expected<Design> d = method == "tustin" ? discrete_tf::tustin(zeros, poles, gain, period_s, prewarp_hz)
                                          : discrete_tf::matched_pole_zero(zeros, poles, gain, period_s);
  if (!d) axis.fail(d.error());
  return d;
}

Json complex_list(const std::vector<std::complex<double>>& values) {
  Json out = Json::array();
  for (const auto& v : values) out.push(Json(std::vector<double>{v.real(), v.imag()}));
  return out;
}

}  // namespace

Status DiscreteTfController::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();

  std::vector<Params> axes = params.items("axes");
  axes_ = axes.size();

  ctx.declare_input(measurement_, "measurement", {}, true);
  ctx.declare_input(reference_, "reference", {}, false);
  const Elements* measurement = ctx.input_source("measurement");
  if (measurement != nullptr) {
    measurement_elements_ = *measurement;
    if (measurement->size() != axes_) {
      params.fail("axes", "one axis per measured element: the measurement has " +
                              std::to_string(measurement->size()) + " elements, axes lists " +
                              std::to_string(axes_));
    }
  }
  if (const Elements* reference = ctx.input_source("reference"); reference != nullptr) {
    if (reference->size() != axes_) {
      params.fail("inputs", "the reference must have " + std::to_string(axes_) + " elements (one per axis), got " +
                                std::to_string(reference->size()));
    } else if (measurement != nullptr && measurement->size() == axes_) {
      for (std::size_t i = 0; i < axes_; ++i) {
        const Element& m = (*measurement)[i];
        const Element& r = (*reference)[i];
        if (canonical_unit(m.unit) != canonical_unit(r.unit)) {
          params.fail("inputs", "reference element '" + r.name + "' is in '" + r.unit + "' but measurement '" +
                                    m.name + "' is in '" + m.unit + "': e = reference - measurement needs equal units");
        }
      }
    }
  }

  for (std::size_t i = 0; i < axes_; ++i) {
    Expected<Design> design = read_axis(axes[i], period_s_);
    designs_.push_back(design ? std::move(*design) : Design{});
  }

  const std::vector<std::string> units = params.texts("output_units", {});
  if (!params.has("output_units")) {
    params.fail("output_units", "one SI unit per axis is required, e.g. [N, N, N*m]");
  } else if (units.size() != axes_) {
    params.fail("output_units", "expected " + std::to_string(axes_) + " units (one per axis), got " +
                                    std::to_string(units.size()));
  }
  std::vector<std::string> names = params.texts("output_names", {});
  if (params.has("output_names") && names.size() != axes_) {
    params.fail("output_names", "expected " + std::to_string(axes_) + " names (one per axis), got " +
                                    std::to_string(names.size()));
  }
  if (!params.has("output_names")) {
    names.clear();
    for (std::size_t i = 0; i < axes_; ++i) {
      names.push_back(i < measurement_elements_.size() ? "u_" + measurement_elements_[i].name
                                                       : "u" + std::to_string(i));
    }
  }
  std::set<std::string> seen;
  for (const std::string& name : names) {
    if (name.empty() || !seen.insert(name).second) {
      params.fail("output_names", "output names must be unique and non-empty ('" + name + "')");
    }
  }

  limits_ = params.numbers("output_limit", std::vector<double>(axes_, 0.0));
  if (limits_.size() == 1 && axes_ > 1) limits_.assign(axes_, limits_.front());
  if (limits_.size() != axes_) {
    params.fail("output_limit", "expected one number or " + std::to_string(axes_) + " (one per axis), got " +
                                    std::to_string(limits_.size()));
  }
  for (double limit : limits_) {
    if (limit < 0.0) params.fail("output_limit", "|u| limits must be >= 0 (0: no limit), got " + number_text(limit));
  }

  if (!params.ok()) return Status::error("invalid parameters");

  for (std::size_t i = 0; i < axes_; ++i) output_elements_.push_back({names[i], units[i]});
  sections_.resize(axes_);
  for (std::size_t i = 0; i < axes_; ++i) sections_[i].configure(designs_[i], limits_[i]);
  error_.assign(axes_, 0.0);
  ctx.declare_output(out_, "out", output_elements_);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status DiscreteTfController::activate() {
  if (measurement_.size() != axes_) {
    return Status::error("controller.discrete_tf: the measurement has " + std::to_string(measurement_.size()) +
                         " elements, expected " + std::to_string(axes_) + " (one per axis)");
  }
  if (reference_.connected() && reference_.size() != axes_) {
    return Status::error("controller.discrete_tf: the reference has " + std::to_string(reference_.size()) +
                         " elements, expected " + std::to_string(axes_));
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    sections_[i].reset();
    out_[i] = 0.0;
  }
  return Status::ok();
}

StepStatus DiscreteTfController::step(const Tick& /*tick*/) noexcept {
  // Locals: the stores below could, as far as the compiler knows, change the ports' pointers.
  const std::size_t axes = axes_;
  const double* measurement = measurement_.data();
  const double* reference = reference_.data();  // nullptr when not connected: a reference of 0
  double* error = error_.data();
  // Every error first, so a fault leaves all axes as they were.
  for (std::size_t i = 0; i < axes; ++i) {
    error[i] = (reference != nullptr ? reference[i] : 0.0) - measurement[i];
    if (!std::isfinite(error[i])) return fault("non-finite measurement or reference");
  }
  double* out = out_.data();
  for (std::size_t i = 0; i < axes; ++i) {
    double u = 0.0;
    if (!sections_[i].step(error[i], u)) return fault("non-finite controller state or output");
    out[i] = u;
  }
  return StepStatus::ok;
}

void DiscreteTfController::describe(Json& out) const {
  out["period_s"] = period_s_;
  out["anti_windup"] = "clamp |u| to output_limit; hold the state while its update pushes further into saturation";
  Json axes = Json::array();
  for (std::size_t i = 0; i < axes_; ++i) {
    const Design& d = designs_[i];
    Json axis = Json::object();
    if (i < measurement_elements_.size()) axis["measurement"] = measurement_elements_[i].name;
    axis["output"] = output_elements_[i].name;
    axis["output_unit"] = output_elements_[i].unit;
    axis["output_limit"] = limits_[i];
    axis["method"] = discrete_tf::to_string(d.method);
    if (d.method != discrete_tf::Method::direct) {
      Json s = Json::object();
      s["zeros"] = d.zeros_s;
      s["poles"] = d.poles_s;
      s["gain"] = d.gain_s;
      axis["s_domain"] = std::move(s);
    }
    if (d.method == discrete_tf::Method::matched) {
      Json m = Json::object();
      m["k"] = d.origin_order;
      m["lim_s^k_D(s)"] = d.low_frequency_gain;
      m["note"] = "K_z chosen so that lim ((z-1)/T)^k D(z) equals lim s^k D(s); zeros at infinity -> z = -1";
      axis["gain_matching"] = std::move(m);
    }
    if (d.method == discrete_tf::Method::tustin) {
      axis["prewarp_hz"] = d.prewarp_hz;
    }
    Json z = Json::object();
    z["gain"] = d.gain_z();
    z["numerator_monic"] = d.monic_numerator();
    z["denominator_monic"] = d.den;
    z["zeros"] = complex_list(discrete_tf::poly_roots(d.num));
    z["poles"] = complex_list(discrete_tf::poly_roots(d.den));
    axis["z_domain"] = std::move(z);
    axis["num_z"] = d.num;
    axis["den_z"] = d.den;
    axes.push(std::move(axis));
  }
  out["axes"] = std::move(axes);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"axes", "list<map>", nullptr,
     "one map per measured element, either {zeros_s: [rad/s], poles_s: [rad/s], gain, discretization: "
     "matched|tustin (default matched), prewarp_hz (tustin only)} for D(s) = gain prod(s-z)/prod(s-p), or "
     "{num_z, den_z} (descending powers of z); order <= 8"},
    {"output_units", "list<text>", nullptr, "SI unit of each output, e.g. [N, N, N*m]"},
    {"output_names", "list<text>", "u_<measurement name>", "name of each output element"},
    {"output_limit", "number|list<number>", "0 (no limit)",
     "per-axis |u| clamp [output unit]; while clamped the state is not updated towards saturation"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "n measured values, one per axis (e.g. kf.pose)"},
    {"reference", PortDirection::in, "optional n references in the measurement's units; 0 when not connected"},
    {"out", PortDirection::out, "n controller outputs u = D(z)(reference - measurement), in output_units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::DiscreteTfController, "controller.discrete_tf", lode::PluginKind::controller, "0.1.0",
            "Per-axis SISO discrete transfer functions (matched pole-zero, Tustin or given D(z)) with clamp",
            lode::plugins::kParams, lode::plugins::kPorts)
