#include "suspension.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "runge_kutta.hpp"

namespace lode::plugins {

namespace {

double sum_of_squares(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return s;
}

/// Non-negative least squares of f ~ p x + q y (two columns): the unconstrained solution if
/// it is non-negative, else the better of the two one-column solutions (the KKT points of a
/// two-variable NNLS). Columns are scaled to unit norm first (d^-4 and d^-2 differ by 1e4).
struct TwoColumnFit {
  double p = 0.0;
  double q = 0.0;
  double cost = 0.0;
};
TwoColumnFit nnls2(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& f) {
  const double sx = std::sqrt(sum_of_squares(x));
  const double sy = std::sqrt(sum_of_squares(y));
  double xx = 0.0, yy = 0.0, xy = 0.0, xf = 0.0, yf = 0.0;
  for (std::size_t k = 0; k < f.size(); ++k) {
    const double xs = x[k] / sx;
    const double ys = y[k] / sy;
    xx += xs * xs;
    yy += ys * ys;
    xy += xs * ys;
    xf += xs * f[k];
    yf += ys * f[k];
  }
  auto cost = [&](double p, double q) {
    double c = 0.0;
    for (std::size_t k = 0; k < f.size(); ++k) {
      const double r = f[k] - p * x[k] - q * y[k];
      c += r * r;
    }
    return c;
  };
  const double det = xx * yy - xy * xy;
  TwoColumnFit best;
  best.cost = INFINITY;
  if (std::abs(det) > 1e-14) {
    const double p = (xf * yy - yf * xy) / det / sx;
    const double q = (yf * xx - xf * xy) / det / sy;
    if (p >= 0.0 && q >= 0.0) return {p, q, cost(p, q)};
  }
  const double p_only = std::max(0.0, xf / xx / sx);
  const double q_only = std::max(0.0, yf / yy / sy);
  const double c_p = cost(p_only, 0.0);
  const double c_q = cost(0.0, q_only);
  best = c_p <= c_q ? TwoColumnFit{p_only, 0.0, c_p} : TwoColumnFit{0.0, q_only, c_q};
  return best;
}

Status check_curve(const std::vector<double>& gap_m, const std::vector<double>& force_n) {
  if (gap_m.size() != force_n.size() || gap_m.size() < 2) {
    return Status::error("need as many forces as gaps, at least 2, got " + std::to_string(gap_m.size()) +
                         " gaps and " + std::to_string(force_n.size()) + " forces");
  }
  for (double d : gap_m) {
    if (!(d > 0.0)) return Status::error("every gap must be > 0 m, got " + number_text(d));
  }
  return Status::ok();
}

}  // namespace

Expected<ForceCoefficientFit> fit_force_coefficients(const std::vector<double>& current_a,
                                                     const std::vector<double>& a,
                                                     const std::vector<double>& b) {
  if (current_a.size() != a.size() || current_a.size() != b.size() || current_a.empty()) {
    return Status::error("current_a, a and b must have the same, non-zero length (got " +
                         std::to_string(current_a.size()) + ", " + std::to_string(a.size()) + ", " +
                         std::to_string(b.size()) + ")");
  }
  const double ii = sum_of_squares(current_a);
  if (!(ii > 0.0)) return Status::error("at least one current must be non-zero to fit b = m i");
  ForceCoefficientFit fit;
  double ib = 0.0;
  for (std::size_t j = 0; j < a.size(); ++j) {
    fit.a_mean += a[j] / static_cast<double>(a.size());  // eq. 11: a treated as constant
    ib += current_a[j] * b[j];
  }
  fit.b_per_current = ib / ii;  // eq. 12: min J_3 = sum (b_j - m i_j)^2 through the origin
  for (std::size_t j = 0; j < b.size(); ++j) {
    const double r = b[j] - fit.b_per_current * current_a[j];
    fit.j3 += r * r;
  }
  return fit;
}

Expected<ForceCurveFit> fit_force_curve(const std::vector<double>& gap_m, const std::vector<double>& force_n) {
  if (Status st = check_curve(gap_m, force_n); !st) return st;
  std::vector<double> d4;
  std::vector<double> d2;
  for (double d : gap_m) {
    d4.push_back(std::pow(d, -4.0));
    d2.push_back(std::pow(d, -2.0));
  }
  const TwoColumnFit fit = nnls2(d4, d2, force_n);
  return ForceCurveFit{fit.p, fit.q, fit.cost};
}

Expected<ForceCurveFitSingle> fit_force_curve_d4(const std::vector<double>& gap_m,
                                                 const std::vector<double>& force_n) {
  if (Status st = check_curve(gap_m, force_n); !st) return st;
  double xx = 0.0, xf = 0.0;
  for (std::size_t k = 0; k < gap_m.size(); ++k) {
    const double x = std::pow(gap_m[k], -4.0);
    xx += x * x;
    xf += x * force_n[k];
  }
  ForceCurveFitSingle fit;
  fit.c = std::max(0.0, xf / xx);  // eq. 8, c >= 0
  for (std::size_t k = 0; k < gap_m.size(); ++k) {
    const double r = force_n[k] - fit.c * std::pow(gap_m[k], -4.0);
    fit.cost += r * r;
  }
  return fit;
}

Suspension::Suspension() {
  const Elements voltage{{"coil_voltage", "V"}};
  const Elements state{{"gap", "m"}, {"velocity", "m/s"}, {"current", "A"}};
  declare_plant_elements(voltage, {{"gap", "m"}, {"coil_voltage", "V"}}, state);
  declare_process_elements(state, voltage);
  apply(SuspensionConfig{});
}

Status Suspension::configure(Params& params) {
  const SuspensionConfig defaults;
  SuspensionConfig c;
  c.mass_kg = params.number("mass_kg", defaults.mass_kg);
  c.gravity_m_s2 = params.number("gravity_m_s2", defaults.gravity_m_s2);
  const bool explicit_a = params.has("force_a_n_m4");
  const bool explicit_b = params.has("force_b_n_m2_per_a");
  c.force_a_n_m4 = params.number("force_a_n_m4", defaults.force_a_n_m4);
  c.force_b_n_m2_per_a = params.number("force_b_n_m2_per_a", defaults.force_b_n_m2_per_a);
  if (std::optional<Params> table = params.optional_child("force_fit")) {
    // Table 3 -> Table 4: the stage-2 fit gives a and b from per-current FEM fits.
    const std::vector<double> currents = table->numbers("current_a");
    const std::vector<double> a = table->numbers("a_n_m4");
    const std::vector<double> b = table->numbers("b_n_m2");
    if (explicit_a || explicit_b) {
      params.fail("force_fit", "give either force_fit or force_a_n_m4/force_b_n_m2_per_a, not both");
    } else if (table->ok()) {
      Expected<ForceCoefficientFit> fit = fit_force_coefficients(currents, a, b);
      if (!fit) {
        table->fail(fit.error());
      } else {
        c.force_a_n_m4 = fit->a_mean;
        c.force_b_n_m2_per_a = fit->b_per_current;
        c.force_fit = fit.value();
      }
    }
  }
  c.coil_decay_1_per_s = params.number("coil_decay_1_per_s", defaults.coil_decay_1_per_s);
  c.coil_gain_a_per_v_s = params.number("coil_gain_a_per_v_s", defaults.coil_gain_a_per_v_s);
  const std::vector<double> limits =
      params.numbers("gap_limits_m", {defaults.gap_limits_m[0], defaults.gap_limits_m[1]}, 2);
  c.initial_gap_m = params.number("initial_gap_m", defaults.initial_gap_m);
  c.initial_velocity_m_s = params.number("initial_velocity_m_s", defaults.initial_velocity_m_s);
  if (params.has("initial_current_a")) c.initial_current_a = params.number("initial_current_a");
  c.substeps = static_cast<int>(params.integer("substeps", defaults.substeps));
  const std::string discretization =
      params.choice("process_discretization", {"euler", "rk4"}, std::string_view("euler"));
  c.process_discretization =
      discretization == "rk4" ? SuspensionDiscretization::rk4 : SuspensionDiscretization::euler;

  params.check(c.mass_kg > 0.0, "mass_kg", "must be > 0 kg, got " + number_text(c.mass_kg));
  params.check(c.gravity_m_s2 >= 0.0, "gravity_m_s2", "must be >= 0 m/s^2, got " + number_text(c.gravity_m_s2));
  params.check(c.force_a_n_m4 >= 0.0, "force_a_n_m4",
               "the magnet-core attraction a must be >= 0 N*m^4, got " + number_text(c.force_a_n_m4));
  params.check(c.force_b_n_m2_per_a > 0.0, "force_b_n_m2_per_a",
               "the coil force constant b must be > 0 N*m^2/A (else the coil cannot act), got " +
                   number_text(c.force_b_n_m2_per_a));
  params.check(c.coil_decay_1_per_s > 0.0, "coil_decay_1_per_s",
               "R/L must be > 0 1/s, got " + number_text(c.coil_decay_1_per_s));
  params.check(c.coil_gain_a_per_v_s > 0.0, "coil_gain_a_per_v_s",
               "1/L must be > 0 A/(V*s), got " + number_text(c.coil_gain_a_per_v_s));
  if (limits.size() == 2) {
    c.gap_limits_m = {limits[0], limits[1]};
    params.check(limits[0] > 0.0 && limits[0] < limits[1], "gap_limits_m",
                 "expected [coil face, floor] with 0 < coil face < floor, got [" + number_text(limits[0]) + ", " +
                     number_text(limits[1]) + "] m");
  }
  params.check(c.initial_gap_m >= c.gap_limits_m[0] && c.initial_gap_m <= c.gap_limits_m[1], "initial_gap_m",
               "must lie within gap_limits_m, got " + number_text(c.initial_gap_m) + " m");
  params.check(c.substeps >= 1 && c.substeps <= 10000, "substeps",
               "must be 1 ... 10000, got " + std::to_string(c.substeps));
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void Suspension::apply(const SuspensionConfig& config) {
  config_ = config;
  initial_current_a_ = config_.initial_current_a.value_or(hold_current_a(config_.initial_gap_m));
  reset();
}

void Suspension::reset() noexcept {
  x_[kGap] = config_.initial_gap_m;
  x_[kVelocity] = config_.initial_velocity_m_s;
  x_[kCurrent] = initial_current_a_;
  // The voltage that has been holding the initial current (its steady state).
  held_voltage_v_ = initial_current_a_ * config_.coil_decay_1_per_s / config_.coil_gain_a_per_v_s;
  stop_contacts_ = 0;
}

namespace {

// The physics as functions of this file, so that propagate() and the RK4 steps inline them:
// the members below are exported (a plugin built position-independent calls its own exported
// functions through the PLT, which the compiler may not inline). Forced inline: out of line,
// the derivative came back through memory, written one double at a time and read two at a
// time, and that store-to-load forwarding failed on each of a UKF's 7 calls per cycle.

[[gnu::always_inline]] inline double attraction(const SuspensionConfig& c, double gap_m, double current_a) noexcept {
  // Below the coil face the force law is meaningless (and d^-4 explodes): hold it there.
  const double d = std::max(gap_m, c.gap_limits_m[0]);
  const double d2 = d * d;
  return c.force_a_n_m4 / (d2 * d2) + c.force_b_n_m2_per_a * current_a / d2;  // eq. 13
}

[[gnu::always_inline]] inline void slope(const SuspensionConfig& c, const double* x, double u, double* dx) noexcept {
  dx[Suspension::kGap] = x[Suspension::kVelocity];
  dx[Suspension::kVelocity] =
      c.gravity_m_s2 - attraction(c, x[Suspension::kGap], x[Suspension::kCurrent]) / c.mass_kg;
  dx[Suspension::kCurrent] = -c.coil_decay_1_per_s * x[Suspension::kCurrent] + c.coil_gain_a_per_v_s * u;
}

}  // namespace

double Suspension::force_n(double gap_m, double current_a) const noexcept {
  return attraction(config_, gap_m, current_a);
}

void Suspension::derivative(const double* x, double u, double* dx) const noexcept { slope(config_, x, u, dx); }

void Suspension::rk4_step(double h, double u, State& x) const noexcept {
  plants::rk4_step(x, h, [&](const State& at, State& dx) { slope(config_, at.data(), u, dx.data()); }, x);
}

void Suspension::enforce_stops(double* x) noexcept {
  if (x[kGap] <= config_.gap_limits_m[0]) {
    if (x[kGap] < config_.gap_limits_m[0] || x[kVelocity] < 0.0) ++stop_contacts_;
    x[kGap] = config_.gap_limits_m[0];
    x[kVelocity] = std::max(x[kVelocity], 0.0);
  } else if (x[kGap] >= config_.gap_limits_m[1]) {
    if (x[kGap] > config_.gap_limits_m[1] || x[kVelocity] > 0.0) ++stop_contacts_;
    x[kGap] = config_.gap_limits_m[1];
    x[kVelocity] = std::min(x[kVelocity], 0.0);
  }
}

void Suspension::advance(double dt_s, const double* u) noexcept {
  held_voltage_v_ = u[kCoilVoltage];
  const double h = dt_s / config_.substeps;
  for (int s = 0; s < config_.substeps; ++s) {
    rk4_step(h, held_voltage_v_, x_);
    enforce_stops(x_.data());
  }
}

void Suspension::output(double* y) const noexcept {
  y[kOutGap] = x_[kGap];
  y[kOutCoilVoltage] = held_voltage_v_;
}

void Suspension::state(double* x) const noexcept {
  for (std::size_t i = 0; i < kStateSize; ++i) x[i] = x_[i];
}

namespace {

/// eq. 33: x(k+1) = x(k) + t_s f(x(k), u(k)), without the copy through a local array that
/// the RK4 branch needs (x_next may be x: everything is read before anything is written).
[[gnu::always_inline]] inline void euler_step(const SuspensionConfig& c, double dt_s, const double* x, double u,
                                              double* x_next) noexcept {
  std::array<double, Suspension::kStateSize> dx;
  slope(c, x, u, dx.data());
  const double gap = x[Suspension::kGap] + dt_s * dx[Suspension::kGap];
  const double velocity = x[Suspension::kVelocity] + dt_s * dx[Suspension::kVelocity];
  const double current = x[Suspension::kCurrent] + dt_s * dx[Suspension::kCurrent];
  x_next[Suspension::kGap] = gap;
  x_next[Suspension::kVelocity] = velocity;
  x_next[Suspension::kCurrent] = current;
}

}  // namespace

void Suspension::propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept {
  if (config_.process_discretization == SuspensionDiscretization::rk4) {
    State next;
    std::copy_n(x, kStateSize, next.begin());
    rk4_step(dt_s, u[kCoilVoltage], next);
    std::copy(next.begin(), next.end(), x_next);
    return;
  }
  euler_step(config_, dt_s, x, u[kCoilVoltage], x_next);
}

void Suspension::propagate_points(double dt_s, const double* x, std::size_t count, const double* u,
                                  double* x_next) const noexcept {
  if (config_.process_discretization == SuspensionDiscretization::rk4) {
    ProcessModel::propagate_points(dt_s, x, count, u, x_next);  // point by point
    return;
  }
  // The points are independent: one loop, each point's divisions free to overlap the next's.
  for (std::size_t i = 0; i < count; ++i)
    euler_step(config_, dt_s, x + i * kStateSize, u[kCoilVoltage], x_next + i * kStateSize);
}

bool Suspension::process_jacobian(double dt_s, const double* x, const double* /*u*/, double* F) const noexcept {
  if (config_.process_discretization != SuspensionDiscretization::euler) return false;
  // The Jacobian of eq. 33 with the mass (derived here): F = I + t_s df/dx,
  //   d(v')/dd = (4 a d^-5 + 2 b i d^-3) / m,  d(v')/di = -b d^-2 / m,  d(i')/di = -R/L.
  const bool on_face = x[kGap] < config_.gap_limits_m[0];  // force held constant there
  const double d = std::max(x[kGap], config_.gap_limits_m[0]);
  // Powers of 1/d and 1/m from two independent divisions (the EKF calls this every cycle,
  // and five divisions, two of them in a chain, were most of its cost).
  const double inverse_d = 1.0 / d;
  const double inverse_m = 1.0 / config_.mass_kg;
  const double inverse_d2 = inverse_d * inverse_d;
  const double inverse_d3 = inverse_d2 * inverse_d;
  const double dacc_dgap =
      on_face ? 0.0
              : (4.0 * config_.force_a_n_m4 * (inverse_d3 * inverse_d2) +
                 2.0 * config_.force_b_n_m2_per_a * x[kCurrent] * inverse_d3) *
                    inverse_m;
  const double dacc_dcurrent = -config_.force_b_n_m2_per_a * inverse_d2 * inverse_m;
  for (std::size_t i = 0; i < kStateSize * kStateSize; ++i) F[i] = 0.0;
  F[kGap * kStateSize + kGap] = 1.0;
  F[kGap * kStateSize + kVelocity] = dt_s;
  F[kVelocity * kStateSize + kGap] = dt_s * dacc_dgap;
  F[kVelocity * kStateSize + kVelocity] = 1.0;
  F[kVelocity * kStateSize + kCurrent] = dt_s * dacc_dcurrent;
  F[kCurrent * kStateSize + kCurrent] = 1.0 - dt_s * config_.coil_decay_1_per_s;
  return true;
}

double Suspension::hold_current_a(double gap_m) const noexcept {
  const double d2 = gap_m * gap_m;
  return (config_.mass_kg * config_.gravity_m_s2 - config_.force_a_n_m4 / (d2 * d2)) * d2 /
         config_.force_b_n_m2_per_a;
}

double Suspension::hold_voltage_v(double gap_m) const noexcept {
  return hold_current_a(gap_m) * config_.coil_decay_1_per_s / config_.coil_gain_a_per_v_s;
}

double Suspension::zero_current_gap_m() const noexcept {
  const double weight = config_.mass_kg * config_.gravity_m_s2;
  return weight > 0.0 ? std::pow(config_.force_a_n_m4 / weight, 0.25) : INFINITY;
}

double Suspension::unstable_pole_rad_s(double gap_m) const noexcept {
  const double d = gap_m;
  const double stiffness = (4.0 * config_.force_a_n_m4 / std::pow(d, 5) +
                            2.0 * config_.force_b_n_m2_per_a * hold_current_a(d) / std::pow(d, 3)) /
                           config_.mass_kg;
  return stiffness > 0.0 ? std::sqrt(stiffness) : 0.0;
}

void Suspension::describe(Json& out) const {
  out["mass_kg"] = config_.mass_kg;
  out["gravity_m_s2"] = config_.gravity_m_s2;
  out["force_a_n_m4"] = config_.force_a_n_m4;
  out["force_b_n_m2_per_a"] = config_.force_b_n_m2_per_a;
  if (config_.force_fit) {
    Json fit = Json::object();
    fit["method"] = "stage-2 fit of eq. 11-12: a = mean of a_n_m4, b = m through the origin";
    fit["a_mean"] = config_.force_fit->a_mean;
    fit["b_per_current"] = config_.force_fit->b_per_current;
    fit["j3"] = config_.force_fit->j3;
    out["force_fit"] = std::move(fit);
  }
  out["coil_decay_1_per_s"] = config_.coil_decay_1_per_s;
  out["coil_gain_a_per_v_s"] = config_.coil_gain_a_per_v_s;
  // Coil parameters implied by eq. 32: L = 1/gain, R = decay L.
  out["coil_inductance_h"] = 1.0 / config_.coil_gain_a_per_v_s;
  out["coil_resistance_ohm"] = config_.coil_decay_1_per_s / config_.coil_gain_a_per_v_s;
  out["coil_time_constant_s"] = 1.0 / config_.coil_decay_1_per_s;
  out["coil_static_gain_a_per_v"] = config_.coil_gain_a_per_v_s / config_.coil_decay_1_per_s;
  out["gap_limits_m"] = std::vector<double>{config_.gap_limits_m[0], config_.gap_limits_m[1]};
  out["zero_current_gap_m"] = zero_current_gap_m();
  out["initial_gap_m"] = config_.initial_gap_m;
  out["initial_current_a"] = initial_current_a_;
  out["integration"] = "RK4, " + std::to_string(config_.substeps) + " substeps per period, ZOH input";
  out["process_discretization"] = config_.process_discretization == SuspensionDiscretization::euler
                                      ? "euler (eq. 33), analytic Jacobian"
                                      : "rk4 (one step per period), numerical Jacobian";
  // Where the magnet can be held, and how unstable it is there (the paper's steps: 22-30 mm).
  Json hold = Json::array();
  for (double gap_mm : {18.0, 20.0, 22.0, 24.0, 26.0, 28.0, 30.0, 32.0}) {
    const double d = 1e-3 * gap_mm;
    Json row = Json::object();
    row["gap_m"] = d;
    row["hold_current_a"] = hold_current_a(d);
    row["hold_voltage_v"] = hold_voltage_v(d);
    row["unstable_pole_rad_s"] = unstable_pole_rad_s(d);
    row["current_gain_m_s2_per_a"] = config_.force_b_n_m2_per_a / (d * d) / config_.mass_kg;
    hold.push(std::move(row));
  }
  out["hold_points"] = std::move(hold);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"mass_kg", "number", "4.35e-3", "moving mass [kg] (Table 1: the magnet alone 4.35 g), > 0"},
    {"gravity_m_s2", "number", "9.81", "gravity [m/s^2] (printed 9.89 in eq. 32, 9.83 in eq. 34)"},
    {"force_a_n_m4", "number", "5.996e-9", "a of eq. 13: magnet-core attraction a d^-4 [N*m^4] (Table 4)"},
    {"force_b_n_m2_per_a", "number", "4.509e-6", "b of eq. 13: coil attraction b i d^-2 [N*m^2/A] (Table 4 m)"},
    {"force_fit", "map", "none",
     "{current_a: [...], a_n_m4: [...], b_n_m2: [...]}: per-current FEM fits (Table 3); a and b then come "
     "from the stage-2 fit of eq. 11-12 (instead of force_a_n_m4/force_b_n_m2_per_a)"},
    {"coil_decay_1_per_s", "number", "165.6", "R/L of the coil, eq. 32 [1/s]"},
    {"coil_gain_a_per_v_s", "number", "61.61", "1/L of the coil, eq. 32 [A/(V*s)]"},
    {"gap_limits_m", "list<number>[2]", "[0.012, 0.050]", "end stops [coil face, floor] [m]"},
    {"initial_gap_m", "number", "0.026", "initial gap [m]"},
    {"initial_velocity_m_s", "number", "0", "initial velocity [m/s] (positive: away from the coil)"},
    {"initial_current_a", "number", "hold current at initial_gap_m", "initial coil current [A]"},
    {"substeps", "integer", "10", "RK4 steps per period in the simulator"},
    {"process_discretization", "text", "euler",
     "estimator model: euler (eq. 33, analytic Jacobian) or rk4 (one RK4 step, numerical Jacobian)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::Suspension, "plant.suspension", lode::PluginKind::plant, "0.1.0",
            "Magnet suspended under an electromagnet (Sensors 2016, eq. 13/32/33): simulator and process model",
            lode::plugins::kParams, lode::kNoPorts)
