#include "npo.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "estimator/describe_json.hpp"
#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace npo {

const char* to_string(Integrator integrator) {
  switch (integrator) {
    case Integrator::exact: return "exact";
    case Integrator::backward_euler: return "backward_euler";
    case Integrator::forward_euler: return "forward_euler";
  }
  return "?";
}

double AxisDesign::spectral_radius() const {
  return std::max(std::abs(discrete_poles[0]), std::abs(discrete_poles[1]));
}

AxisDesign design_axis(double mass, double d, double a, double period_s, Integrator integrator) {
  AxisDesign axis;
  axis.mass = mass;
  axis.d = d;
  axis.a = a;
  axis.period_s = period_s;
  const double t = period_s;
  Eigen::Matrix2d ad;
  ad << 1.0, t, 0.0, 1.0;

  switch (integrator) {
    case Integrator::exact: {
      // Error dynamics of Eq. 15-18 per axis (J = I, C = 0), e = (p~, v~):
      //   p~' = -a p~ + v~,   m v~' = -d p~.
      math::Matrix error_dynamics(2, 2);
      error_dynamics << -a, 1.0, -d / mass, 0.0;
      const math::Matrix sampled = math::expm(error_dynamics * t);
      // E = Ad - [g + h, T h] = exp(A_e T): the second column fixes h, the first g.
      const Eigen::Matrix2d difference = ad - Eigen::Matrix2d(sampled);
      axis.h_p = difference(0, 1) / t;
      axis.h_v = difference(1, 1) / t;
      axis.g_p = difference(0, 0) - axis.h_p;
      axis.g_v = difference(1, 0) - axis.h_v;
      break;
    }
    case Integrator::backward_euler:
      // P^ = (P^- + aT Z)/(1 + aT) = P^- + aT/(1 + aT) nu^-; V^ = V^- + T (d/m) (Z - P^).
      axis.h_p = a * t / (1.0 + a * t);
      axis.h_v = t * (d / mass) / (1.0 + a * t);
      break;
    case Integrator::forward_euler:
      // Explicit Euler of the injection L (Z_k - P^_k) over [t_k, t_k+1].
      axis.g_p = a * t;
      axis.g_v = t * d / mass;
      break;
  }
  axis.transition = ad;
  axis.transition(0, 0) -= axis.g_p + axis.h_p;
  axis.transition(1, 0) -= axis.g_v + axis.h_v;
  axis.transition(0, 1) -= t * axis.h_p;
  axis.transition(1, 1) -= t * axis.h_v;

  // m s^2 + m a s + d = 0.
  const std::complex<double> discriminant = std::sqrt(std::complex<double>(a * a - 4.0 * d / mass, 0.0));
  axis.continuous_poles = {0.5 * (-a + discriminant), 0.5 * (-a - discriminant)};
  const Eigen::EigenSolver<Eigen::Matrix2d> solver(axis.transition, false);
  axis.discrete_poles = {solver.eigenvalues()(0), solver.eigenvalues()(1)};
  return axis;
}

Eigen::Vector2d bias_response(const AxisDesign& axis) {
  const double t = axis.period_s;
  // The observer integrates F + b: its prediction moves by Bd b more than the plant.
  const Eigen::Vector2d bd(0.5 * t * t / axis.mass, t / axis.mass);
  Eigen::Matrix2d i_minus_hc = Eigen::Matrix2d::Identity();
  i_minus_hc(0, 0) -= axis.h_p;
  i_minus_hc(1, 0) -= axis.h_v;
  return -(Eigen::Matrix2d::Identity() - axis.transition).inverse() * (i_minus_hc * bd);
}

bool lyapunov_non_increasing(const AxisDesign& axis) {
  // W(e) = 1/2 e' P e with P = diag(d, m); W(E e) <= W(e) for all e iff P - E'PE >= 0.
  const Eigen::Matrix2d p = Eigen::Vector2d(axis.d, axis.mass).asDiagonal();
  const Eigen::Matrix2d decrease = p - axis.transition.transpose() * p * axis.transition;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(0.5 * (decrease + decrease.transpose()));
  // Relative to the size of P: rounding in E'PE is ~1e-16 of it.
  return solver.eigenvalues().minCoeff() >= -1e-12 * p.diagonal().maxCoeff();
}

}  // namespace npo

namespace {

using npo::kAxes;
using npo::kStates;
using estimator::matrix_json;

std::string complex_text(std::complex<double> z) {
  if (z.imag() == 0.0) return number_text(z.real());
  return number_text(z.real()) + (z.imag() < 0.0 ? " - " : " + ") + number_text(std::abs(z.imag())) + "i";
}

/// One number for every axis or one per axis.
std::array<double, kAxes> per_axis(Params& params, std::string_view key, const std::vector<double>& values) {
  std::array<double, kAxes> out{};
  if (values.size() == 1) {
    out.fill(values.front());
  } else if (values.size() == kAxes) {
    std::copy(values.begin(), values.end(), out.begin());
  } else {
    params.fail(key, "expected one number or 6 (x, y, z, phi, theta, psi), got " + std::to_string(values.size()));
  }
  return out;
}

/// The layout the observer needs from a process model: pose, then body velocity, force inputs.
constexpr const char* kStateUnits[kStates] = {"m", "m", "m", "rad", "rad", "rad",
                                              "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s"};
constexpr const char* kInputUnits[kAxes] = {"N", "N", "N", "N*m", "N*m", "N*m"};
constexpr const char* kMeasurementUnits[kAxes] = {"m", "m", "m", "rad", "rad", "rad"};

/// Relative size of cross-coupling accepted when reading M off the model at rest. A product of
/// inertia couples axes at O(I_xy / I); gravity tipped by a period's worth of rotation only at
/// O(g T^2) ~ 1e-6, which the per-axis design may ignore.
constexpr double kDecouplingTolerance = 1e-3;

Json complex_json(std::complex<double> z) {
  Json j = Json::object();
  j["re"] = z.real();
  j["im"] = z.imag();
  return j;
}

}  // namespace

Status NonlinearPassiveObserver::identify_mass(Params& params, AxisValues& mass) {
  // M_i = T / dV_i for a unit F_i held over T from rest, relative to the force-free motion
  // (which removes gravity if the model has it). A rigid body at rest is decoupled: F_i moves
  // V_i alone, and P_i by T^2 / (2 M_i).
  State rest{};
  State free_motion{};
  AxisValues zero{};
  model_->propagate(period_s_, rest.data(), zero.data(), free_motion.data());
  for (std::size_t i = 0; i < kAxes; ++i) rest_acceleration_[i] = free_motion[kAxes + i] / period_s_;
  for (std::size_t i = 0; i < kAxes; ++i) {
    AxisValues unit{};
    unit[i] = 1.0;
    State pushed{};
    model_->propagate(period_s_, rest.data(), unit.data(), pushed.data());
    const double dv = pushed[kAxes + i] - free_motion[kAxes + i];
    if (!(dv > 0.0) || !std::isfinite(dv)) {
      params.fail("model", "process model '" + model_name_ + "': a unit " + model_->process_inputs()[i].name +
                               " does not accelerate " + model_->process_state()[kAxes + i].name +
                               " (dV = " + number_text(dv) + "); it is not a rigid body with inputs in this order");
      return Status::error("invalid model");
    }
    mass[i] = period_s_ / dv;
    for (std::size_t j = 0; j < kStates; ++j) {
      if (j == i || j == kAxes + i) continue;
      const double cross = std::abs(pushed[j] - free_motion[j]);
      if (cross > kDecouplingTolerance * dv) {
        params.fail("model", "process model '" + model_name_ + "': at rest a unit " +
                                 model_->process_inputs()[i].name + " also moves " +
                                 model_->process_state()[j].name + " by " + number_text(cross) +
                                 "; the observer's per-axis gains need a decoupled M (principal axes)");
        return Status::error("invalid model");
      }
    }
  }
  return Status::ok();
}

void NonlinearPassiveObserver::read_gains(Params& params, const AxisValues& mass, AxisValues& d, AxisValues& a) {
  // Read every key (so none is reported unknown), then decide which form was given.
  const std::vector<double> d0 = params.numbers("d0", std::vector<double>{});
  const std::vector<double> a0 = params.numbers("a0_per_s", std::vector<double>{});
  const std::vector<double> frequency = params.numbers("observer_frequency_hz", std::vector<double>{});
  const std::vector<double> damping = params.numbers("observer_damping", std::vector<double>{});
  const bool direct = !d0.empty() || !a0.empty();
  gains_from_tuning_ = !frequency.empty() || !damping.empty();
  if (direct && gains_from_tuning_) {
    params.fail("d0", "give either d0 and a0_per_s (Table 2) or observer_frequency_hz and observer_damping "
                      "(a = 2 zeta w, d = m w^2), not both");
    return;
  }
  if (!direct && !gains_from_tuning_) {
    params.fail("d0", "no observer gains: give d0 [N/m, N*m/rad] and a0_per_s [1/s] (Table 2: 100 and 1e4), or "
                      "observer_frequency_hz and observer_damping");
    return;
  }
  if (gains_from_tuning_) {
    if (frequency.empty()) params.fail("observer_frequency_hz", "missing: the tuning rule needs w_o and zeta_o");
    if (damping.empty()) params.fail("observer_damping", "missing: the tuning rule needs w_o and zeta_o");
    if (frequency.empty() || damping.empty()) return;
    observer_frequency_hz_ = per_axis(params, "observer_frequency_hz", frequency);
    observer_damping_ = per_axis(params, "observer_damping", damping);
    for (std::size_t i = 0; i < kAxes; ++i) {
      const double w = 2.0 * std::numbers::pi * observer_frequency_hz_[i];
      params.check(observer_frequency_hz_[i] > 0.0, "observer_frequency_hz",
                   "must be > 0 Hz, got " + number_text(observer_frequency_hz_[i]));
      params.check(observer_damping_[i] > 0.0, "observer_damping",
                   "must be > 0, got " + number_text(observer_damping_[i]));
      a[i] = 2.0 * observer_damping_[i] * w;  // tuning rule (derived, not in the paper)
      d[i] = mass[i] * w * w;
    }
    return;
  }
  if (d0.empty()) params.fail("d0", "missing: a0_per_s was given, D0 is needed too");
  if (a0.empty()) params.fail("a0_per_s", "missing: d0 was given, A0 is needed too");
  if (d0.empty() || a0.empty()) return;
  d = per_axis(params, "d0", d0);
  a = per_axis(params, "a0_per_s", a0);
  for (std::size_t i = 0; i < kAxes; ++i) {
    // The passivity argument (Eq. 19) needs d_i > 0 and a_i > 0.
    params.check(d[i] > 0.0, "d0", "every D0 entry must be > 0 (passivity, Eq. 19), got " + number_text(d[i]));
    params.check(a[i] > 0.0, "a0_per_s", "every A0 entry must be > 0 1/s (passivity), got " + number_text(a[i]));
  }
}

Status NonlinearPassiveObserver::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();

  model_name_ = params.text("model");
  const std::string integrator = params.choice("integrator", {"exact", "backward_euler", "forward_euler"},
                                               std::string_view("exact"));
  integrator_ = integrator == "backward_euler"  ? npo::Integrator::backward_euler
                : integrator == "forward_euler" ? npo::Integrator::forward_euler
                                                : npo::Integrator::exact;
  dynamics_ = params.choice("dynamics", {"nonlinear", "linear"}, std::string_view("nonlinear")) == "linear"
                  ? npo::Dynamics::linear
                  : npo::Dynamics::nonlinear;
  initialize_from_first_measurement_ = params.flag("initialize_from_first_measurement", true);
  const std::vector<double> initial_pose = params.numbers("initial_pose", std::vector<double>(kAxes, 0.0), kAxes);
  const std::vector<double> initial_velocity =
      params.numbers("initial_velocity", std::vector<double>(kAxes, 0.0), kAxes);
  for (std::size_t i = 0; i < kAxes && i < initial_pose.size() && i < initial_velocity.size(); ++i) {
    initial_[i] = initial_pose[i];
    initial_[kAxes + i] = initial_velocity[i];
  }

  // Ports are declared before anything can fail, so the pipeline reports the real problem.
  ctx.declare_input(measurement_, "measurement", {}, true);
  ctx.declare_input(force_, "force", {}, true);

  // --- the process model: the plant copy of Eq. 11 and 13 ---------------------------------
  if (!model_name_.empty()) model_ = ctx.process_model("model");
  AxisValues mass{};
  bool model_ok = model_ != nullptr;
  if (model_ok) {
    const Elements& states = model_->process_state();
    const Elements& inputs = model_->process_inputs();
    bool layout = states.size() == kStates && inputs.size() == kAxes;
    for (std::size_t i = 0; layout && i < kStates; ++i) layout = units_compatible(states[i].unit, kStateUnits[i]);
    for (std::size_t i = 0; layout && i < kAxes; ++i) layout = units_compatible(inputs[i].unit, kInputUnits[i]);
    if (!layout) {
      params.fail("model", "process model '" + model_name_ +
                               "' must have the state [x, y, z: m, phi, theta, psi: rad, u, v, w: m/s, p, q, r: "
                               "rad/s] and the inputs [fx, fy, fz: N, tx, ty, tz: N*m] (e.g. plant.rigid_body6)");
      model_ok = false;
    } else {
      model_ok = identify_mass(params, mass).is_ok();
    }
  }

  // --- gains --------------------------------------------------------------------------------
  AxisValues d{};
  AxisValues a{};
  if (model_ok) {
    read_gains(params, mass, d, a);
  } else {
    // Still read them, so they are not reported as unknown on top of the model problem.
    params.numbers("d0", std::vector<double>{});
    params.numbers("a0_per_s", std::vector<double>{});
    params.numbers("observer_frequency_hz", std::vector<double>{});
    params.numbers("observer_damping", std::vector<double>{});
  }

  // --- inputs: the measured pose and the force by name ----------------------------------------
  const Elements* measurement_source = ctx.input_source("measurement");
  if (measurement_source == nullptr) {
    params.fail("inputs", "the measurement input must be connected to a configured output with the pose "
                          "[x, y, z: m, phi, theta, psi: rad]");
  } else {
    bool pose = measurement_source->size() == kAxes;
    for (std::size_t i = 0; pose && i < kAxes; ++i) {
      pose = units_compatible((*measurement_source)[i].unit, kMeasurementUnits[i]);
    }
    if (!pose) {
      params.fail("inputs", "the measurement must be the 6-DOF pose [m, m, m, rad, rad, rad], got " +
                                std::to_string(measurement_source->size()) + " elements");
    } else {
      measurement_elements_ = *measurement_source;
    }
  }
  const Elements* force_source = ctx.input_source("force");
  if (model_ok) {
    if (force_source == nullptr) {
      params.fail("inputs", "the force input must be connected to a configured output holding the model's inputs "
                            "(fx ... tz) by name, e.g. board.truth of io.sim with plant.rigid_body6");
    } else {
      for (std::size_t i = 0; i < kAxes; ++i) {
        const Element& need = model_->process_inputs()[i];
        const auto found = std::find_if(force_source->begin(), force_source->end(),
                                        [&](const Element& e) { return e.name == need.name; });
        if (found == force_source->end()) {
          params.fail("inputs", "the force input has no element '" + need.name + "' [" + need.unit +
                                    "] (the observer needs F, Eq. 11)");
        } else if (!units_compatible(found->unit, need.unit)) {
          params.fail("inputs", "force element '" + need.name + "' is in [" + found->unit + "], expected [" +
                                    need.unit + "]");
        } else {
          force_index_[i] = static_cast<std::size_t>(found - force_source->begin());
        }
      }
    }
  }

  // --- design and stability of the discrete update -------------------------------------------
  if (model_ok && params.ok()) {
    for (std::size_t i = 0; i < kAxes; ++i) {
      axes_[i] = npo::design_axis(mass[i], d[i], a[i], period_s_, integrator_);
      const double radius = axes_[i].spectral_radius();
      if (!(radius < 1.0)) {
        const auto& worst = std::abs(axes_[i].discrete_poles[0]) >= std::abs(axes_[i].discrete_poles[1])
                                ? axes_[i].discrete_poles[0]
                                : axes_[i].discrete_poles[1];
        params.fail("integrator", std::string(npo::to_string(integrator_)) + " is unstable on axis " +
                                      model_->process_state()[i].name + ": a0 T = " + number_text(a[i] * period_s_) +
                                      ", error eigenvalue " + complex_text(worst) + " (|z| = " +
                                      number_text(std::abs(worst)) +
                                      " >= 1); use exact or backward_euler, or smaller gains");
      }
    }
  }

  if (model_ok) {
    const Elements& states = model_->process_state();
    velocity_elements_.assign(states.begin() + kAxes, states.end());
  } else {
    velocity_elements_ = {{"u", "m/s"}, {"v", "m/s"}, {"w", "m/s"}, {"p", "rad/s"}, {"q", "rad/s"}, {"r", "rad/s"}};
  }
  if (measurement_elements_.empty()) {
    measurement_elements_ = {{"x", "m"}, {"y", "m"}, {"z", "m"}, {"phi", "rad"}, {"theta", "rad"}, {"psi", "rad"}};
  }
  Elements fd;
  for (const Element& e : measurement_elements_) fd.push_back({e.name + "_dot", e.unit + "/s"});
  ctx.declare_output(velocity_, "velocity", velocity_elements_);
  ctx.declare_output(pose_, "pose", measurement_elements_);
  ctx.declare_output(innovation_, "innovation", measurement_elements_);
  ctx.declare_output(fd_velocity_, "fd_velocity", fd);
  Elements state = model_ok ? model_->process_state() : measurement_elements_;
  if (!model_ok) state.insert(state.end(), velocity_elements_.begin(), velocity_elements_.end());
  ctx.declare_output(state_, "state", state);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status NonlinearPassiveObserver::activate() {
  if (measurement_.size() != kAxes) {
    return Status::error("estimator.npo: the measurement has " + std::to_string(measurement_.size()) +
                         " elements, expected 6");
  }
  estimate_ = initial_;
  residual_.fill(0.0);
  previous_measurement_.fill(0.0);
  fd_.fill(0.0);
  first_cycle_ = true;
  publish();
  return Status::ok();
}

void NonlinearPassiveObserver::predict(const AxisValues& force, State& predicted) const noexcept {
  if (dynamics_ == npo::Dynamics::nonlinear) {
    model_->propagate(period_s_, estimate_.data(), force.data(), predicted.data());
    return;
  }
  // Six decoupled double integrators with the force held (exact ZOH, J = I, C = 0), plus the
  // model's force-free acceleration at rest (gravity at zero attitude, if the model has it).
  for (std::size_t i = 0; i < kAxes; ++i) {
    const double acceleration = force[i] / axes_[i].mass + rest_acceleration_[i];
    predicted[i] = estimate_[i] + period_s_ * estimate_[kAxes + i] + 0.5 * period_s_ * period_s_ * acceleration;
    predicted[kAxes + i] = estimate_[kAxes + i] + period_s_ * acceleration;
  }
}

StepStatus NonlinearPassiveObserver::step(const Tick& /*tick*/) noexcept {
  AxisValues z{};
  AxisValues force{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    z[i] = measurement_[i];
    force[i] = force_[force_index_[i]];
    if (!std::isfinite(z[i])) return fault("non-finite measurement");
    if (!std::isfinite(force[i])) return fault("non-finite force");
  }

  if (first_cycle_) {
    // No period has elapsed: start from Z_0 (or the configured estimate) without an update.
    if (initialize_from_first_measurement_) {
      for (std::size_t i = 0; i < kAxes; ++i) estimate_[i] = z[i];
    }
    for (std::size_t i = 0; i < kAxes; ++i) {
      residual_[i] = z[i] - estimate_[i];
      previous_measurement_[i] = z[i];
      fd_[i] = 0.0;
    }
    first_cycle_ = false;
    publish();
    return StepStatus::ok;
  }

  State predicted{};
  predict(force, predicted);
  State updated{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    const npo::AxisDesign& axis = axes_[i];
    const double innovation = z[i] - predicted[i];  // nu^- = Z_{k+1} - P^-
    updated[i] = predicted[i] + axis.g_p * residual_[i] + axis.h_p * innovation;
    updated[kAxes + i] = predicted[kAxes + i] + axis.g_v * residual_[i] + axis.h_v * innovation;
  }
  for (double value : updated) {
    if (!std::isfinite(value)) return fault("observer state is not finite");
  }
  estimate_ = updated;
  for (std::size_t i = 0; i < kAxes; ++i) {
    residual_[i] = z[i] - estimate_[i];
    fd_[i] = (z[i] - previous_measurement_[i]) / period_s_;
    previous_measurement_[i] = z[i];
  }
  publish();
  return StepStatus::ok;
}

void NonlinearPassiveObserver::publish() noexcept {
  for (std::size_t i = 0; i < kAxes; ++i) {
    pose_[i] = estimate_[i];
    velocity_[i] = estimate_[kAxes + i];
    innovation_[i] = residual_[i];
    fd_velocity_[i] = fd_[i];
  }
  for (std::size_t i = 0; i < kStates; ++i) state_[i] = estimate_[i];
}

void NonlinearPassiveObserver::describe(Json& out) const {
  out["model"] = model_name_;
  out["dynamics"] = dynamics_ == npo::Dynamics::nonlinear
                        ? "nonlinear: the process model (Eq. 9-10 with C(V^), R_BF, E) predicts"
                        : "linear: six decoupled double integrators (J = I, C = 0)";
  out["integrator"] = npo::to_string(integrator_);
  out["update"] = integrator_ == npo::Integrator::exact
                      ? "E = exp(A_e T): the continuous error dynamics (Eq. 15-18) sampled exactly"
                  : integrator_ == npo::Integrator::backward_euler
                      ? "P^ implicit in A0: (P^- + aT Z)/(1 + aT); V^ += T D0/M (Z - P^)"
                      : "explicit Euler of the injection: P^ += aT nu_k, V^ += T D0/M nu_k";
  out["force_free_acceleration_at_rest"] = std::vector<double>(rest_acceleration_.begin(), rest_acceleration_.end());
  out["gains_from"] = gains_from_tuning_ ? "tuning rule a = 2 zeta w, d = m w^2 (not in the paper)" : "d0, a0_per_s";
  out["period_s"] = period_s_;
  out["initialize_from_first_measurement"] = initialize_from_first_measurement_;
  Json axes = Json::array();
  for (std::size_t i = 0; i < kAxes; ++i) {
    const npo::AxisDesign& ax = axes_[i];
    const bool rotation = i >= 3;
    Json j = Json::object();
    j["axis"] = i < measurement_elements_.size() ? measurement_elements_[i].name : std::to_string(i);
    j["velocity"] = i < velocity_elements_.size() ? velocity_elements_[i].name : std::to_string(i);
    j[rotation ? "inertia_kg_m2" : "mass_kg"] = ax.mass;
    j[rotation ? "d_n_m_per_rad" : "d_n_per_m"] = ax.d;
    j["a_per_s"] = ax.a;
    if (gains_from_tuning_) {
      j["observer_frequency_hz"] = observer_frequency_hz_[i];
      j["observer_damping"] = observer_damping_[i];
    }
    Json poles = Json::array();
    Json time_constants = Json::array();
    for (const auto& s : ax.continuous_poles) {
      poles.push(complex_json(s));
      time_constants.push(s.real() < 0.0 ? -1.0 / s.real() : HUGE_VAL);
    }
    j["error_poles_rad_s"] = std::move(poles);  // roots of m s^2 + m a s + d
    j["time_constants_s"] = std::move(time_constants);
    j["crossover_rad_s"] = ax.d / (ax.mass * ax.a);  // below: s Z, above: F / m
    Json z = Json::array();
    for (const auto& p : ax.discrete_poles) {
      Json pj = complex_json(p);
      pj["abs"] = std::abs(p);
      z.push(std::move(pj));
    }
    j["error_eigenvalues_z"] = std::move(z);
    j["gains_previous_residual"] = std::vector<double>{ax.g_p, ax.g_v};
    j["gains_innovation"] = std::vector<double>{ax.h_p, ax.h_v};
    j["error_transition"] = matrix_json(ax.transition);
    j["w_non_increasing"] = npo::lyapunov_non_increasing(ax);
    const Eigen::Vector2d bias = npo::bias_response(ax);
    Json b = Json::object();
    b[rotation ? "pose_error_rad_per_n_m" : "pose_error_m_per_n"] = bias(0);
    b[rotation ? "velocity_error_rad_s_per_n_m" : "velocity_error_m_s_per_n"] = bias(1);
    b["continuous_velocity_error"] = -ax.a / ax.d;  // v~ = -a b / d (check S8)
    j["steady_error_per_unit_force_bias"] = std::move(b);
    axes.push(std::move(j));
  }
  out["axes"] = std::move(axes);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"model", "text", nullptr,
     "name of a process model in `models:` with state [P (m, rad), V_B (m/s, rad/s)] and inputs [fx ... tz], "
     "e.g. plant.rigid_body6; the observer's copy of Eq. 9-10"},
    {"d0", "number|list<number>[6]", "none",
     "D0 (Eq. 11) per axis [N/m for x, y, z; N*m/rad for phi, theta, psi], > 0; Table 2: 100"},
    {"a0_per_s", "number|list<number>[6]", "none", "A0 (Eq. 13) per axis [1/s], > 0; Table 2: 1e4 (or 1e-4: README)"},
    {"observer_frequency_hz", "number|list<number>[6]", "none",
     "instead of d0/a0: error-dynamics natural frequency f_o; d = m (2 pi f_o)^2 (not in the paper)"},
    {"observer_damping", "number|list<number>[6]", "none", "with observer_frequency_hz: zeta_o; a = 2 zeta_o w_o"},
    {"integrator", "text", "exact",
     "exact (sampled error dynamics), backward_euler (implicit in A0) or forward_euler (refused when unstable)"},
    {"dynamics", "text", "nonlinear",
     "nonlinear (the process model: C(V^), R_BF, E) or linear (decoupled double integrators, J = I, C = 0)"},
    {"initialize_from_first_measurement", "bool", "true", "P^_0 = Z_0 (false: P^_0 = initial_pose)"},
    {"initial_pose", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "P^_0 [m, rad] when not initialised from Z_0"},
    {"initial_velocity", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "V^_0 [m/s, rad/s], body frame"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "Z: measured (filtered) pose x, y, z [m], phi, theta, psi [rad]"},
    {"force", PortDirection::in, "F held over the last period: a port holding the model's inputs fx ... tz by name [N, N*m]"},
    {"velocity", PortDirection::out, "V^_B: u, v, w [m/s], p, q, r [rad/s] (Eq. 12)"},
    {"pose", PortDirection::out, "P^ (Eq. 14), names and units of the measurement"},
    {"innovation", PortDirection::out, "Z_k - P^_k after the update"},
    {"fd_velocity", PortDirection::out, "(Z_k - Z_{k-1}) / T: the paper's finite-difference 'measured velocity' [m/s, rad/s]"},
    {"state", PortDirection::out, "[P^, V^_B]: the process model's 12 states (as io.sim's plant_state)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::NonlinearPassiveObserver, "estimator.npo", lode::PluginKind::estimator, "0.1.0",
            "Nonlinear passive observer of 6-DOF body velocity (Gutierrez & Li 2024, Eq. 11-14) with an exact "
            "discrete update",
            lode::plugins::kParams, lode::plugins::kPorts)
