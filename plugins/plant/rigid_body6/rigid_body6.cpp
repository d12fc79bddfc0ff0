#include "rigid_body6.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "plant_parameters.hpp"
#include "runge_kutta.hpp"

namespace lode::plugins {

namespace rigid_body6 {

namespace {

/// The sines and cosines of the three attitude angles, each computed once: a derivative needs
/// cos/sin phi and cos theta in both R_BF and E (the RK4 step evaluates four derivatives).
struct AttitudeTrig {
  double cf, sf, ct, st, cp, sp;
  AttitudeTrig(double phi, double theta, double psi) noexcept
      : cf(std::cos(phi)), sf(std::sin(phi)), ct(std::cos(theta)), st(std::sin(theta)), cp(std::cos(psi)),
        sp(std::sin(psi)) {}
};

Matrix3 rotation_body_to_fixed(const AttitudeTrig& a) noexcept {
  const double cf = a.cf, sf = a.sf, ct = a.ct, st = a.st, cp = a.cp, sp = a.sp;
  // R_BF = Rz(psi) Ry(theta) Rx(phi) (Appendix A, signs from standard z-y-x kinematics).
  return Matrix3{{{ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp},
                  {ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp},
                  {-st, sf * ct, cf * ct}}};
}

Matrix3 euler_rate_matrix(const AttitudeTrig& a, double theta) noexcept {
  const double cf = a.cf, sf = a.sf;
  const double tt = std::tan(theta), sec = 1.0 / a.ct;
  return Matrix3{{{1.0, sf * tt, cf * tt}, {0.0, cf, -sf}, {0.0, sf * sec, cf * sec}}};
}

}  // namespace

Matrix3 rotation_body_to_fixed(double phi, double theta, double psi) noexcept {
  return rotation_body_to_fixed(AttitudeTrig(phi, theta, psi));
}

Matrix3 euler_rate_matrix(double phi, double theta) noexcept {
  return euler_rate_matrix(AttitudeTrig(phi, theta, 0.0), theta);
}

void derivative(const Physics& physics, const State& x, const Input& u, State& dxdt) noexcept {
  const AttitudeTrig trig(x[kPhi], x[kTheta], x[kPsi]);
  const Matrix3 r_bf = rotation_body_to_fixed(trig);
  const Matrix3 e = euler_rate_matrix(trig, x[kTheta]);
  const double vu = x[kU], vv = x[kV], vw = x[kW];
  const double p = x[kP], q = x[kQ], r = x[kR];

  // Eq. 10: translation P' = R_BF v, attitude Theta' = E Omega.
  for (std::size_t i = 0; i < 3; ++i) {
    dxdt[kX + i] = r_bf[i][0] * vu + r_bf[i][1] * vv + r_bf[i][2] * vw;
    dxdt[kPhi + i] = e[i][0] * p + e[i][1] * q + e[i][2] * r;
  }

  // Eq. 9, translational rows: v' = F/m + R_FB [0 0 -g] - Omega x v. R_FB = R_BF^T, so the
  // body-frame gravity is -g times the third row of R_BF.
  const double g = physics.gravity_m_s2;
  const double inv_m = 1.0 / physics.mass_kg;
  dxdt[kU] = u[kFx] * inv_m - g * r_bf[2][0] - (q * vw - r * vv);
  dxdt[kV] = u[kFy] * inv_m - g * r_bf[2][1] - (r * vu - p * vw);
  dxdt[kW] = u[kFz] * inv_m - g * r_bf[2][2] - (p * vv - q * vu);

  // Eq. 9, rotational rows (Euler's equations): I Omega' = T - Omega x (I Omega).
  const double ix = physics.inertia_kg_m2[0], iy = physics.inertia_kg_m2[1], iz = physics.inertia_kg_m2[2];
  dxdt[kP] = (u[kTx] - (iz - iy) * q * r) / ix;
  dxdt[kQ] = (u[kTy] - (ix - iz) * r * p) / iy;
  dxdt[kR] = (u[kTz] - (iy - ix) * p * q) / iz;
}

void rk4_step(const Physics& physics, const State& x, const Input& u, double h, State& x_next) noexcept {
  plants::rk4_step(x, h, [&](const State& at, State& slope) { derivative(physics, at, u, slope); }, x_next);
}

void integrate(const Physics& physics, std::size_t substeps, const State& x, const Input& u, double dt,
               State& x_next) noexcept {
  const double h = dt / static_cast<double>(substeps);
  State current = x;
  for (std::size_t s = 0; s < substeps; ++s) {
    rk4_step(physics, current, u, h, x_next);
    current = x_next;
  }
  x_next = current;
}

}  // namespace rigid_body6

namespace {

using namespace rigid_body6;

constexpr std::int64_t kMaxSubsteps = 1000;

}  // namespace

RigidBody6::RigidBody6() {
  const Elements wrench{{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}};
  const Elements state{{"x", "m"},     {"y", "m"},       {"z", "m"},     {"phi", "rad"},
                       {"theta", "rad"}, {"psi", "rad"},   {"u", "m/s"},   {"v", "m/s"},
                       {"w", "m/s"},   {"p", "rad/s"},   {"q", "rad/s"}, {"r", "rad/s"}};
  Elements outputs(state.begin(), state.begin() + kPoseSize);  // the pose, then the applied wrench read back
  outputs.insert(outputs.end(), wrench.begin(), wrench.end());
  declare_plant_elements(wrench, std::move(outputs), state);
  declare_process_elements(state, wrench);
  apply(RigidBody6Config{});
}

Status RigidBody6::configure(Params& params) {
  const RigidBody6Config defaults;
  RigidBody6Config c;
  c.physics.mass_kg = params.number("mass_kg", defaults.physics.mass_kg);
  plants::read_numbers_into(params, "inertia_kg_m2", c.physics.inertia_kg_m2);  // default: Table 1
  c.physics.gravity_m_s2 = params.number("gravity_m_s2", defaults.physics.gravity_m_s2);
  plants::read_initial_condition(params, c.initial, c.initial_velocity);
  const std::int64_t substeps = params.integer("substeps", 1);

  params.check(c.physics.mass_kg > 0.0, "mass_kg", "must be > 0 kg, got " + number_text(c.physics.mass_kg));
  for (std::size_t i = 0; i < 3; ++i) {
    params.check(c.physics.inertia_kg_m2[i] > 0.0, "inertia_kg_m2",
                 "principal inertias Ix, Iy, Iz must be > 0 kg*m^2, got " + number_text(c.physics.inertia_kg_m2[i]) +
                     " for axis " + std::to_string(i));
  }
  params.check(c.physics.gravity_m_s2 >= 0.0, "gravity_m_s2",
               "must be >= 0 m/s^2 (z points up; gravity pulls along -z), got " + number_text(c.physics.gravity_m_s2));
  // E (Eq. 10) is singular at theta = +-90 deg: refuse a start within 1 deg of it.
  params.check(std::abs(std::cos(c.initial[kTheta])) > std::sin(std::numbers::pi / 180.0), "initial",
               "initial pitch theta = " + number_text(c.initial[kTheta]) +
                   " rad is at the Euler-angle singularity (cos(theta) = 0) of E");
  if (substeps < 1 || substeps > kMaxSubsteps) {
    params.fail("substeps", "must be within 1 ... 1000, got " + std::to_string(substeps));
  } else {
    c.substeps = static_cast<std::size_t>(substeps);
  }
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void RigidBody6::apply(const RigidBody6Config& config) {
  config_ = config;
  reset();
}

void RigidBody6::reset() noexcept {
  plants::write_initial_state(config_.initial, config_.initial_velocity, x_.data());
  applied_.fill(0.0);
}

void RigidBody6::advance(double dt_s, const double* u) noexcept {
  for (std::size_t i = 0; i < kInputSize; ++i) applied_[i] = u[i];
  State next;
  integrate(config_.physics, config_.substeps, x_, applied_, dt_s, next);
  x_ = next;
}

void RigidBody6::output(double* y) const noexcept {
  for (std::size_t i = 0; i < kPoseSize; ++i) y[i] = x_[i];
  for (std::size_t i = 0; i < kInputSize; ++i) y[kPoseSize + i] = applied_[i];
}

void RigidBody6::state(double* x) const noexcept {
  for (std::size_t i = 0; i < kStateSize; ++i) x[i] = x_[i];
}

void RigidBody6::propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept {
  State from;
  Input held;
  for (std::size_t i = 0; i < kStateSize; ++i) from[i] = x[i];
  for (std::size_t i = 0; i < kInputSize; ++i) held[i] = u[i];
  State to;
  integrate(config_.physics, config_.substeps, from, held, dt_s, to);
  for (std::size_t i = 0; i < kStateSize; ++i) x_next[i] = to[i];
}

void RigidBody6::describe(Json& out) const {
  const Physics& ph = config_.physics;
  out["mass_kg"] = ph.mass_kg;
  out["inertia_kg_m2"] = std::vector<double>(ph.inertia_kg_m2.begin(), ph.inertia_kg_m2.end());
  out["gravity_m_s2"] = ph.gravity_m_s2;
  plants::describe_initial_condition(out, config_.initial, config_.initial_velocity);
  out["M"] = std::vector<double>{ph.mass_kg, ph.mass_kg, ph.mass_kg, ph.inertia_kg_m2[0], ph.inertia_kg_m2[1],
                                 ph.inertia_kg_m2[2]};
  out["integration"] = "RK4, " + std::to_string(config_.substeps) +
                       " substep(s) per advance, input held (ZOH); the process model uses the same code";
  out["equations"] = "M V' + C(V) V = F + G_B (Eq. 9), P' = blockdiag(R_BF, E) V (Eq. 10), z-y-x Euler angles";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"mass_kg", "number", "0.931", "stage mass m (Table 1), > 0"},
    {"inertia_kg_m2", "list<number>[3]", "[1.799e-3, 1.834e-3, 3.336e-3]",
     "principal inertias Ix, Iy, Iz (Table 1, x 10^-3 kg*m^2), each > 0"},
    {"gravity_m_s2", "number", "0",
     "gravity along -z of the fixed frame (z up, assumed); 0 when the permanent magnets carry the weight"},
    {"initial", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "initial pose x, y, z [m], phi, theta, psi [rad]"},
    {"initial_velocity", "list<number>[6]", "[0, 0, 0, 0, 0, 0]",
     "initial body velocity u, v, w [m/s], p, q, r [rad/s]"},
    {"substeps", "integer", "1", "RK4 steps per advance()/propagate(), 1 ... 1000"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::RigidBody6, "plant.rigid_body6", lode::PluginKind::plant, "0.1.0",
            "Free 6-DOF rigid body, Newton-Euler with Coriolis/gyroscopic terms and z-y-x Euler kinematics "
            "(Gutierrez & Li 2024, Eq. 9-10); also a process model",
            lode::plugins::kParams, lode::kNoPorts)
