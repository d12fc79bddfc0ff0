#include "planar_stage.hpp"

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "plant_parameters.hpp"

namespace lode::plugins {

PlanarStage::PlanarStage() {
  declare_plant_elements({{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}},
                         {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}},
                         {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}, {"vx", "m/s"}, {"vy", "m/s"}, {"omega_z", "rad/s"}});
  apply(PlanarStageConfig{});
}

Status PlanarStage::configure(Params& params) {
  const PlanarStageConfig defaults;
  PlanarStageConfig c;
  c.mass_kg = params.number("mass_kg", defaults.mass_kg);
  c.inertia_kg_m2 = params.number("inertia_kg_m2", defaults.inertia_kg_m2);
  plants::read_initial_condition(params, c.initial, c.initial_velocity);
  c.yaw_coupling_m = params.number("yaw_coupling_m", defaults.yaw_coupling_m);
  c.disturbance_torque_n_m =
      params.number("disturbance_torque_n_m", defaults.disturbance_torque_n_m);

  params.check(c.mass_kg > 0.0, "mass_kg", "must be > 0 kg, got " + number_text(c.mass_kg));
  params.check(c.inertia_kg_m2 > 0.0, "inertia_kg_m2",
               "must be > 0 kg*m^2, got " + number_text(c.inertia_kg_m2));
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void PlanarStage::apply(const PlanarStageConfig& config) {
  config_ = config;
  reset();
}

void PlanarStage::reset() noexcept {
  plants::write_initial_state(config_.initial, config_.initial_velocity, x_.data());
}

void PlanarStage::advance(double dt_s, const double* u) noexcept {
  // Accelerations are constant over dt because the inputs are held (ZOH), so the double
  // integrator is integrated exactly: p += v dt + a dt^2/2, v += a dt (eq. 4.44-4.47).
  const double ax = u[kFx] / config_.mass_kg;
  const double ay = u[kFy] / config_.mass_kg;
  // Yaw moment: commanded torque, the X actuator's lever arm (the thesis's force asymmetry)
  // and the constant cable torque.
  const double alpha =
      (u[kTz] + config_.yaw_coupling_m * u[kFx] + config_.disturbance_torque_n_m) /
      config_.inertia_kg_m2;
  const double half_dt2 = 0.5 * dt_s * dt_s;
  x_[kX] += x_[kVx] * dt_s + ax * half_dt2;
  x_[kY] += x_[kVy] * dt_s + ay * half_dt2;
  x_[kThetaZ] += x_[kOmegaZ] * dt_s + alpha * half_dt2;
  x_[kVx] += ax * dt_s;
  x_[kVy] += ay * dt_s;
  x_[kOmegaZ] += alpha * dt_s;
}

void PlanarStage::output(double* y) const noexcept {
  y[0] = x_[kX];
  y[1] = x_[kY];
  y[2] = x_[kThetaZ];
}

void PlanarStage::state(double* x) const noexcept {
  for (std::size_t i = 0; i < kStateSize; ++i) x[i] = x_[i];
}

void PlanarStage::describe(Json& out) const {
  out["mass_kg"] = config_.mass_kg;
  out["inertia_kg_m2"] = config_.inertia_kg_m2;
  out["yaw_coupling_m"] = config_.yaw_coupling_m;
  out["disturbance_torque_n_m"] = config_.disturbance_torque_n_m;
  plants::describe_initial_condition(out, config_.initial, config_.initial_velocity);
  // The ZOH-discretised double integrator per axis (the DSP's view of the plant):
  // y(z)/u(z) = T^2 (z + 1) / (2 m (z - 1)^2); its gain factor 1/m and 1/Iz.
  out["x_y_gain_1_per_kg"] = 1.0 / config_.mass_kg;
  out["theta_gain_1_per_kg_m2"] = 1.0 / config_.inertia_kg_m2;
  out["integration"] = "exact zero-order hold";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"mass_kg", "number", "6.20", "platen mass (thesis eq. 4.44), > 0"},
    {"inertia_kg_m2", "number", "0.054", "yaw inertia Iz (thesis eq. 4.46), > 0"},
    {"initial", "list<number>[3]", "[0, 0, 0]", "initial x [m], y [m], theta_z [rad]"},
    {"initial_velocity", "list<number>[3]", "[0, 0, 0]",
     "initial vx [m/s], vy [m/s], omega_z [rad/s]"},
    {"yaw_coupling_m", "number", "0",
     "lever arm by which fx also produces the yaw moment fx*lever (force asymmetry, Kawato 2005)"},
    {"disturbance_torque_n_m", "number", "0", "constant yaw disturbance torque (cables)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::PlanarStage, "plant.planar_stage", lode::PluginKind::plant, "0.1.0",
            "Planar 3-DOF rigid platen on air bearings, exact ZOH integration (Kawato eq. 4.44-4.47)",
            lode::plugins::kParams, lode::kNoPorts)
