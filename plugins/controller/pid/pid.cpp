#include "pid.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace pid {

Recursion design(const Gains& g, double period_s) noexcept {
  const double T = period_s;
  // Without a derivative part there is no filter pole: p = 0 and the denominator is (1 - z^-1).
  const bool derivative = g.kd != 0.0;
  const double N = g.derivative_filter_rad_s;
  const double p = derivative ? (2.0 - N * T) / (2.0 + N * T) : 0.0;
  const double c = derivative ? 2.0 * g.kd * N / (2.0 + N * T) : 0.0;
  const double h = 0.5 * g.ki * T;
  // Everything over the common denominator (1 - z^-1)(1 - p z^-1):
  //   P: kp (1 - z^-1)(1 - p z^-1),  I: h (1 + z^-1)(1 - p z^-1),  D: c (1 - z^-1)^2.
  const std::array<double, 3> P{g.kp, -g.kp * (1.0 + p), g.kp * p};
  const std::array<double, 3> I{h, h * (1.0 - p), -h * p};
  const std::array<double, 3> D{c, -2.0 * c, c};
  Recursion r;
  for (std::size_t j = 0; j < 3; ++j) {
    r.measurement_numerator[j] = P[j] + I[j] + D[j];
    r.reference_numerator[j] = g.setpoint_weight_p * P[j] + I[j] + g.setpoint_weight_d * D[j];
  }
  r.error_numerator = r.measurement_numerator;
  r.denominator = {-(1.0 + p), p};
  return r;
}

Recursion from_coefficients(const std::vector<double>& numerator, const std::vector<double>& denominator) {
  Recursion r;
  const double a0 = denominator.at(0);
  for (std::size_t j = 0; j < 3; ++j) {
    r.error_numerator[j] = j < numerator.size() ? numerator[j] / a0 : 0.0;
  }
  r.reference_numerator = r.error_numerator;
  r.measurement_numerator = r.error_numerator;
  r.denominator = {denominator.size() > 1 ? denominator[1] / a0 : 0.0,
                   denominator.size() > 2 ? denominator[2] / a0 : 0.0};
  return r;
}

std::vector<std::array<double, 2>> quadratic_roots(double c0, double c1, double c2) {
  std::vector<std::array<double, 2>> roots;
  if (c0 == 0.0) {
    if (c1 != 0.0) roots.push_back({-c2 / c1, 0.0});
    return roots;
  }
  const std::complex<double> disc = std::sqrt(std::complex<double>(c1 * c1 - 4.0 * c0 * c2, 0.0));
  // The numerically stable pair: q = -(c1 + sign(c1) sqrt(disc)) / 2, roots q/c0 and c2/q.
  const std::complex<double> q = -0.5 * (c1 + (c1 >= 0.0 ? disc : -disc));
  const std::complex<double> z1 = q / c0;
  const std::complex<double> z2 = q != 0.0 ? std::complex<double>(c2) / q : std::complex<double>(0.0);
  roots.push_back({z1.real(), z1.imag()});
  roots.push_back({z2.real(), z2.imag()});
  std::sort(roots.begin(), roots.end(), [](const auto& a, const auto& b) { return a[0] > b[0]; });
  return roots;
}

}  // namespace pid

namespace {

std::string text_of(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", value);
  return buffer;
}

std::string names_of(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out;
}

/// One number for every axis or one per axis.
std::vector<double> per_axis(Params& params, std::string_view key, std::vector<double> fallback, std::size_t axes) {
  return params.one_or_each(key, params.numbers(key, std::move(fallback)), axes, "axis");
}

std::size_t index_of(const Elements& elements, const std::string& name) {
  for (std::size_t i = 0; i < elements.size(); ++i)
    if (elements[i].name == name) return i;
  return elements.size();
}

Json roots_json(const std::vector<std::array<double, 2>>& roots) {
  Json out = Json::array();
  for (const auto& z : roots) {
    Json r = Json::object();
    r["re"] = z[0];
    r["im"] = z[1];
    r["abs"] = std::hypot(z[0], z[1]);
    out.push(std::move(r));
  }
  return out;
}

}  // namespace

Status PidController::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();
  const std::vector<std::string> axis_names = params.texts("axes", {});
  ctx.declare_input(measurement_, "measurement", {}, true);
  ctx.declare_input(reference_, "reference", {}, false);

  // Which elements are controlled: `axes`, else the reference's elements, else the measurement's.
  const Elements* measurement = ctx.input_source("measurement");
  const Elements* reference = ctx.input_source("reference");
  controlled_.clear();
  if (measurement == nullptr) {
    params.fail("inputs", "the measurement input must be connected to a configured block's output");
  } else if (!axis_names.empty()) {
    for (const std::string& name : axis_names) {
      const std::size_t i = index_of(*measurement, name);
      if (i == measurement->size()) {
        params.fail("axes", "no element '" + name + "' in the measurement (" + names_of(*measurement) + ")");
      } else {
        controlled_.push_back((*measurement)[i]);
      }
    }
  } else if (reference != nullptr) {
    for (std::size_t k = 0; k < reference->size(); ++k) {
      const std::size_t i = index_of(*measurement, (*reference)[k].name);
      if (i < measurement->size()) {
        controlled_.push_back((*measurement)[i]);
      } else if (measurement->size() == reference->size()) {
        controlled_.push_back((*measurement)[k]);
      } else {
        params.fail("inputs", "reference element '" + (*reference)[k].name + "' is not in the measurement (" +
                                  names_of(*measurement) + ")");
      }
    }
  } else {
    controlled_ = *measurement;
  }
  axes_ = controlled_.size();
  if (measurement != nullptr && params.ok() && (axes_ == 0 || axes_ > pid::kMaxAxes)) {
    params.fail("inputs", "1 to " + std::to_string(pid::kMaxAxes) + " axes are supported, got " + std::to_string(axes_));
  }
  const std::size_t n = std::max<std::size_t>(axes_, 1);
  for (std::size_t k = 0; k < axes_ && k < pid::kMaxAxes && measurement != nullptr; ++k) {
    measurement_index_[k] = index_of(*measurement, controlled_[k].name);
    if (reference == nullptr) continue;
    std::size_t r = index_of(*reference, controlled_[k].name);
    if (r == reference->size() && reference->size() == axes_) r = k;
    if (r == reference->size()) {
      params.fail("inputs", "the reference has no element '" + controlled_[k].name + "' (" + names_of(*reference) + ")");
      continue;
    }
    reference_index_[k] = r;
    if (!units_compatible((*reference)[r].unit, controlled_[k].unit)) {
      params.fail("inputs", "reference '" + (*reference)[r].name + "' is in " + (*reference)[r].unit +
                                ", the measurement in " + controlled_[k].unit);
    }
  }

  // The difference equation: from gains or given directly (eq. 35).
  const bool has_gains = params.has("kp") || params.has("ki") || params.has("kd");
  std::optional<Params> coefficients = params.optional_child("coefficients");
  const std::vector<double> kp = per_axis(params, "kp", {0.0}, n);
  const std::vector<double> ki = per_axis(params, "ki", {0.0}, n);
  const std::vector<double> kd = per_axis(params, "kd", {0.0}, n);
  const std::vector<double> filter = per_axis(params, "derivative_filter_rad_s", {0.0}, n);
  const std::vector<double> beta = per_axis(params, "setpoint_weight_p", {1.0}, n);
  const std::vector<double> gamma = per_axis(params, "setpoint_weight_d", {1.0}, n);
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> lower = per_axis(params, "output_min", {-inf}, n);
  const std::vector<double> upper = per_axis(params, "output_max", {inf}, n);
  std::vector<double> initial = per_axis(params, "initial_output", {0.0}, n);
  const std::vector<std::string> names = params.texts("output_names", {});
  const std::vector<std::string> units = params.texts("output_units", {});

  std::vector<double> numerator;
  std::vector<double> denominator;
  from_gains_ = coefficients == std::nullopt;
  if (coefficients) {
    numerator = coefficients->numbers("numerator");
    denominator = coefficients->numbers("denominator");
    if (has_gains || params.has("derivative_filter_rad_s") || params.has("setpoint_weight_p") ||
        params.has("setpoint_weight_d")) {
      params.fail("coefficients", "give either coefficients (eq. 35 form) or kp/ki/kd (with "
                                  "derivative_filter_rad_s and setpoint weights), not both");
    }
    if (numerator.empty() || numerator.size() > 3) {
      coefficients->fail("numerator", "expected 1 to 3 numbers b0, b1, b2 (on e(k), e(k-1), e(k-2)), got " +
                                          std::to_string(numerator.size()));
    }
    if (denominator.empty() || denominator.size() > 3 || denominator[0] == 0.0) {
      coefficients->fail("denominator", "expected 1 to 3 numbers a0, a1, a2 with a0 != 0 (a0 u(k) + a1 u(k-1) + "
                                        "a2 u(k-2) = ...), e.g. [1, -1.604, 0.603]");
    }
  } else if (!has_gains) {
    params.fail("kp", "give PID gains (kp, ki, kd) or the coefficients of the difference equation");
  }
  for (std::size_t k = 0; k < n && from_gains_; ++k) {
    if (kd[k] != 0.0 && !(filter[k] > 0.0)) {
      params.fail("derivative_filter_rad_s", "a derivative part needs its filter N > 0 rad/s (kd N s/(s + N)); "
                                             "without it Tustin puts a pole at z = -1");
    }
    if (filter[k] < 0.0) params.fail("derivative_filter_rad_s", "must be >= 0, got " + text_of(filter[k]));
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (!(lower[k] < upper[k])) {
      params.fail("output_min", "output_min must be < output_max, got " + text_of(lower[k]) + " and " + text_of(upper[k]));
    }
    if (!params.has("initial_output")) initial[k] = std::clamp(0.0, lower[k], upper[k]);
    if (initial[k] < lower[k] || initial[k] > upper[k]) {
      params.fail("initial_output", "must lie within [output_min, output_max], got " + text_of(initial[k]));
    }
  }
  if (!names.empty() && names.size() != n) {
    params.fail("output_names", "expected " + std::to_string(n) + " names (one per axis), got " + std::to_string(names.size()));
  }
  if (!units.empty() && units.size() != n && units.size() != 1) {
    params.fail("output_units", "expected 1 or " + std::to_string(n) + " units, got " + std::to_string(units.size()));
  }
  if (!params.ok()) return Status::error("invalid parameters");

  gains_.clear();
  Elements outputs;
  for (std::size_t k = 0; k < axes_; ++k) {
    Axis& a = axis_[k];
    if (from_gains_) {
      const pid::Gains g{kp[k], ki[k], kd[k], filter[k], beta[k], gamma[k]};
      gains_.push_back(g);
      a.recursion = pid::design(g, period_s_);
    } else {
      a.recursion = pid::from_coefficients(numerator, denominator);
    }
    a.output_min = lower[k];
    a.output_max = upper[k];
    a.initial_output = initial[k];
    const std::string name = names.empty() ? "u_" + controlled_[k].name : names[k];
    const std::string unit = units.empty() ? "1" : units.size() == 1 ? units[0] : units[k];
    outputs.push_back({name, unit});
  }
  outputs_ = outputs;
  ctx.declare_output(out_, "out", outputs);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status PidController::activate() {
  for (std::size_t k = 0; k < axes_; ++k) {
    Axis& a = axis_[k];
    a.u1 = a.u2 = a.initial_output;
    a.clamped = false;
    out_[k] = a.initial_output;
  }
  first_ = true;
  saturations_.store(0, std::memory_order_relaxed);
  return Status::ok();
}

StepStatus PidController::step(const Tick& /*tick*/) noexcept {
  for (std::size_t k = 0; k < axes_; ++k) {
    const double y = measurement_[measurement_index_[k]];
    const double r = reference_.connected() ? reference_[reference_index_[k]] : 0.0;
    if (!std::isfinite(y) || !std::isfinite(r)) return fault("non-finite measurement or reference");
  }
  bool saturated = false;
  for (std::size_t k = 0; k < axes_; ++k) {
    Axis& a = axis_[k];
    const double y = measurement_[measurement_index_[k]];
    const double r = reference_.connected() ? reference_[reference_index_[k]] : 0.0;
    if (first_) {
      // No history yet: as if r, y and u had always been what they are now (bumpless start:
      // the first output is initial_output plus the integral of the first error, and from
      // then on every part acts on changes; in positional terms the integrator starts at
      // initial_output - kp (beta r - y)).
      a.r1 = a.r2 = r;
      a.y1 = a.y2 = y;
    }
    const pid::Recursion& c = a.recursion;
    // eq. 35: the unclamped value of the recursion, then the clamp (f1, f2).
    const double v = -c.denominator[0] * a.u1 - c.denominator[1] * a.u2 +
                     (c.reference_numerator[0] * r + c.reference_numerator[1] * a.r1 + c.reference_numerator[2] * a.r2) -
                     (c.measurement_numerator[0] * y + c.measurement_numerator[1] * a.y1 +
                      c.measurement_numerator[2] * a.y2);
    const double u = std::clamp(v, a.output_min, a.output_max);
    saturated = saturated || u != v;
    a.u2 = a.u1;
    a.u1 = u;  // the clamped value: the anti-windup
    a.clamped = u != v;
    a.r2 = a.r1;
    a.r1 = r;
    a.y2 = a.y1;
    a.y1 = y;
    out_[k] = u;
  }
  if (saturated) saturations_.fetch_add(1, std::memory_order_relaxed);
  first_ = false;
  return StepStatus::ok;
}

std::vector<Tunable> PidController::tunables() const {
  struct KnobDoc {
    const char* key;
    const char* description;
  };
  static constexpr KnobDoc kKnobs[] = {
      {"kp", "proportional gain; bumpless (the integrator absorbs the change)"},
      {"ki", "integral gain; bumpless (only future increments change)"},
      {"kd", "derivative gain; bumpless, filter state kept; != 0 needs derivative_filter_rad_s > 0"},
      {"output_min", "lower output limit, < output_max; applies from the next output"},
      {"output_max", "upper output limit, > output_min; applies from the next output"},
  };
  auto unit_of = [&](std::size_t knob, std::size_t k) {
    const std::string& out = outputs_[k].unit;
    const std::string& in = controlled_[k].unit;
    switch (knob) {
      case 0: return out + "/" + in;
      case 1: return out + "/(" + in + "*s)";
      case 2: return out + "*s/" + in;
      default: return out;
    }
  };
  std::vector<Tunable> list;
  for (std::size_t knob = first_knob(); knob < 5; ++knob) {
    list.push_back({kKnobs[knob].key, unit_of(knob, 0), -1e300, 1e300, false,
                    std::string(kKnobs[knob].description) + (axes_ > 1 ? " (every axis)" : "")});
    for (std::size_t k = 0; axes_ > 1 && k < axes_; ++k) {
      list.push_back({std::string(kKnobs[knob].key) + "." + controlled_[k].name, unit_of(knob, k), -1e300, 1e300,
                      false, std::string(kKnobs[knob].description) + " (axis " + controlled_[k].name + ")"});
    }
  }
  return list;
}

bool PidController::locate(std::size_t index, Knob& knob, std::size_t& first_axis,
                           std::size_t& end_axis) const noexcept {
  const std::size_t stride = knob_stride();
  const std::size_t k = first_knob() + index / stride;
  if (axes_ == 0 || k > static_cast<std::size_t>(Knob::output_max)) return false;
  knob = static_cast<Knob>(k);
  const std::size_t slot = index % stride;  // 0: every axis, 1 + i: axis i
  first_axis = slot == 0 ? 0 : slot - 1;
  end_axis = slot == 0 ? axes_ : slot;
  return true;
}

double PidController::tunable_value(std::size_t index) const noexcept {
  Knob knob{};
  std::size_t first = 0, end = 0;
  if (!locate(index, knob, first, end)) return 0.0;
  switch (knob) {
    case Knob::kp: return gains_[first].kp;
    case Knob::ki: return gains_[first].ki;
    case Knob::kd: return gains_[first].kd;
    case Knob::output_min: return axis_[first].output_min;
    case Knob::output_max: return axis_[first].output_max;
  }
  return 0.0;
}

void PidController::rebase_for_new_gains(std::size_t k, const pid::Gains& next) noexcept {
  // Positionally u = P + I + kd Df, with Df the filtered derivative of d = gamma r - y
  // (Df(k) = p Df(k-1) + g (d(k) - d(k-1)), g = 2N/(2 + N T)). Bumpless transfer keeps u(k-1)
  // and Df and lets I absorb the change, so that
  //   u(k) = u(k-1) + dP'(k) + dI'(k) + kd' dDf(k),   dDf(k) = p dDf(k-1) + g (dd(k) - dd(k-1)).
  // The recursion computes u(k) = u(k-1) + p (u(k-1) - u(k-2)) + [numerator' on the history]
  // = u(k-1) + dP'(k) + dI'(k) + c' (dd(k) - dd(k-1)) + p (u(k-1) - u(k-2) - dP'(k-1) - dI'(k-1)),
  // so u(k-2) is restated to make the last bracket kd' dDf(k-1).
  Axis& a = axis_[k];
  if (first_) return;  // no history yet: the first step starts it from the new gains
  const pid::Gains& old = gains_[k];
  const double T = period_s_;
  const double e1 = a.r1 - a.y1, e2 = a.r2 - a.y2;
  auto p_increment = [&](const pid::Gains& g) {
    return g.kp * ((g.setpoint_weight_p * a.r1 - a.y1) - (g.setpoint_weight_p * a.r2 - a.y2));
  };
  auto i_increment = [&](const pid::Gains& g) { return 0.5 * g.ki * T * (e1 + e2); };
  // The derivative part's last increment under the old gains (unknown after a clamp, whose
  // u(k-1) - u(k-2) is not the PID's own: then the filter is taken at rest).
  const double old_d_increment =
      (old.kd != 0.0 && !a.clamped) ? (a.u1 - a.u2) - p_increment(old) - i_increment(old) : 0.0;
  const double new_d_increment = old.kd != 0.0 ? old_d_increment * (next.kd / old.kd) : 0.0;
  a.u2 = a.u1 - (p_increment(next) + i_increment(next) + new_d_increment);
  a.clamped = false;
}

bool PidController::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  Knob knob{};
  std::size_t first = 0, end = 0;
  if (!locate(index, knob, first, end)) {
    why = "no such parameter";
    return false;
  }
  if (!std::isfinite(value)) {
    why = "the value must be finite";
    return false;
  }
  // Check every affected axis before changing any: all or nothing.
  for (std::size_t k = first; k < end; ++k) {
    if (knob == Knob::kd && value != 0.0 && !(gains_[k].derivative_filter_rad_s > 0.0)) {
      why = "kd != 0 needs derivative_filter_rad_s > 0, which is configured 0 (not tunable)";
      return false;
    }
    if (knob == Knob::output_min && !(value < axis_[k].output_max)) {
      why = "output_min must be < output_max";
      return false;
    }
    if (knob == Knob::output_max && !(value > axis_[k].output_min)) {
      why = "output_max must be > output_min";
      return false;
    }
  }
  for (std::size_t k = first; k < end; ++k) {
    Axis& a = axis_[k];
    switch (knob) {
      case Knob::output_min: a.output_min = value; continue;
      case Knob::output_max: a.output_max = value; continue;
      default: break;
    }
    pid::Gains next = gains_[k];
    (knob == Knob::kp ? next.kp : knob == Knob::ki ? next.ki : next.kd) = value;
    // kd switched on or off moves the filter pole p (0 without a derivative part): the
    // restated history covers that too, as the recursion below is rebuilt from `next`.
    rebase_for_new_gains(k, next);
    gains_[k] = next;
    a.recursion = pid::design(next, period_s_);
  }
  return true;
}

void PidController::describe(Json& out) const {
  out["period_s"] = period_s_;
  out["form"] = from_gains_ ? "designed from kp, ki, kd, N (Tustin)" : "coefficients given directly (eq. 35 form)";
  out["error"] = "e = reference - measurement";
  out["anti_windup"] = "the recursion remembers the clamped output (eq. 35 f1/f2)";
  Json axes = Json::array();
  for (std::size_t k = 0; k < axes_; ++k) {
    const Axis& a = axis_[k];
    const pid::Recursion& c = a.recursion;
    Json j = Json::object();
    j["measurement"] = controlled_[k].name + " [" + controlled_[k].unit + "]";
    if (from_gains_) {
      const pid::Gains& g = gains_[k];
      j["kp"] = g.kp;
      j["ki"] = g.ki;
      j["kd"] = g.kd;
      j["derivative_filter_rad_s"] = g.derivative_filter_rad_s;
      j["setpoint_weight_p"] = g.setpoint_weight_p;
      j["setpoint_weight_d"] = g.setpoint_weight_d;
    }
    // u(k) = -a1 u(k-1) - a2 u(k-2) + b0 e(k) + b1 e(k-1) + b2 e(k-2): the eq. 35 coefficients.
    j["numerator_e"] = std::vector<double>(c.error_numerator.begin(), c.error_numerator.end());
    j["numerator_reference"] = std::vector<double>(c.reference_numerator.begin(), c.reference_numerator.end());
    j["denominator"] = std::vector<double>{1.0, c.denominator[0], c.denominator[1]};
    j["recursion"] = "u(k) = " + text_of(-c.denominator[0]) + " u(k-1) + " + text_of(-c.denominator[1]) +
                     " u(k-2) + " + text_of(c.error_numerator[0]) + " e(k) + " + text_of(c.error_numerator[1]) +
                     " e(k-1) + " + text_of(c.error_numerator[2]) + " e(k-2)";
    j["poles_z"] = roots_json(pid::quadratic_roots(1.0, c.denominator[0], c.denominator[1]));
    j["zeros_z"] = roots_json(pid::quadratic_roots(c.error_numerator[0], c.error_numerator[1], c.error_numerator[2]));
    j["output_min"] = a.output_min;
    j["output_max"] = a.output_max;
    j["initial_output"] = a.initial_output;
    axes.push(std::move(j));
  }
  out["axes"] = std::move(axes);
  out["saturated_cycles"] = static_cast<std::uint64_t>(saturations_.load(std::memory_order_relaxed));
}

namespace {

constexpr ParamDoc kParams[] = {
    {"axes", "list<text>", "reference's elements, else all measurement elements",
     "names of the measurement elements to control (e.g. [gap] of ukf.state)"},
    {"kp", "number|list<number>", "0", "proportional gain [output unit / measurement unit], per axis"},
    {"ki", "number|list<number>", "0", "integral gain [output unit / (measurement unit * s)]"},
    {"kd", "number|list<number>", "0", "derivative gain [output unit * s / measurement unit]"},
    {"derivative_filter_rad_s", "number|list<number>", "0 (required when kd != 0)",
     "N of kd N s/(s + N) [rad/s]; p = (2 - N T)/(2 + N T)"},
    {"setpoint_weight_p", "number|list<number>", "1", "beta: P acts on beta r - y"},
    {"setpoint_weight_d", "number|list<number>", "1", "gamma: D acts on gamma r - y"},
    {"coefficients", "map", "none",
     "{numerator: [b0, b1, b2], denominator: [a0, a1, a2]}: the recursion directly (eq. 35: [-623.9, 1020, "
     "-386.8], [1, -1.604, 0.603]); instead of the gains"},
    {"output_min", "number|list<number>", "-inf", "lower output limit (eq. 35: 0.5 V)"},
    {"output_max", "number|list<number>", "+inf", "upper output limit (eq. 35: 3 V)"},
    {"initial_output", "number|list<number>", "0 clamped to the limits",
     "u(-1) = u(-2): the output the loop starts from (bumpless), e.g. the hold voltage"},
    {"output_names", "list<text>", "u_<measurement name>", "output element names (e.g. [coil_voltage])"},
    {"output_units", "list<text>", "1", "output units, one or one per axis (e.g. [V])"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "the controlled elements by name (e.g. ukf.state: gap [m])"},
    {"reference", PortDirection::in, "optional setpoints, same names/units (0 when unconnected)"},
    {"out", PortDirection::out, "clamped command, output_names [output_units]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::PidController, "controller.pid", lode::PluginKind::controller, "0.1.0",
            "Discrete PID, recursive form of Sensors 2016 eq. 35, output clamp with anti-windup, 2-DOF weights",
            lode::plugins::kParams, lode::plugins::kPorts)
