#include "maglev6.hpp"

#include <Eigen/LU>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "lode/sdk/json_eigen.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "plant_parameters.hpp"

namespace lode::plugins {

namespace {

std::vector<double> row_major(const Eigen::Matrix3d& m) {
  std::vector<double> out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out.push_back(m(i, j));
  return out;
}

Eigen::Matrix3d matrix3(const std::vector<double>& values) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const auto k = static_cast<std::size_t>(3 * i + j);
      if (k < values.size()) m(i, j) = values[k];
    }
  return m;
}

/// Reads a 3x3 row-major matrix and checks it is finite and invertible: a singular B means
/// the three motors cannot move the three axes of the mode independently.
Eigen::Matrix3d read_input_matrix(Params& params, std::string_view key, const Eigen::Matrix3d& fallback,
                                  const char* axes) {
  const Eigen::Matrix3d m = matrix3(params.numbers(key, row_major(fallback), 9));
  if (!m.allFinite()) {
    params.fail(key, "must be finite");
  } else {
    const double det = m.determinant();
    const double scale = m.cwiseAbs().maxCoeff();
    if (!(std::abs(det) > 1e-12 * scale * scale * scale)) {
      params.fail(key, std::string("is singular (det = ") + number_text(det) + "): motors A, B, C cannot move " +
                           axes + " independently");
    }
  }
  return m;
}

}  // namespace

Maglev6::Maglev6() {
  const Elements currents{{"iq_a", "A"}, {"iq_b", "A"}, {"iq_c", "A"}, {"id_a", "A"}, {"id_b", "A"}, {"id_c", "A"}};
  const Elements state{{"x", "m"},         {"y", "m"},         {"theta_z", "rad"},   {"z", "m"},
                       {"theta_x", "rad"}, {"theta_y", "rad"}, {"vx", "m/s"},        {"vy", "m/s"},
                       {"omega_z", "rad/s"}, {"vz", "m/s"},    {"omega_x", "rad/s"}, {"omega_y", "rad/s"}};
  const Elements pose(state.begin(), state.begin() + kAxes);
  declare_plant_elements(currents, pose, state);
  declare_process_elements(state, currents);
  apply(Maglev6Config{});
}

Status Maglev6::configure(Params& params) {
  const Maglev6Config defaults;
  Maglev6Config c;
  c.mass_kg = params.number("mass_kg", defaults.mass_kg);
  c.inertia_xx_kg_m2 = params.number("inertia_xx_kg_m2", defaults.inertia_xx_kg_m2);
  c.inertia_yy_kg_m2 = params.number("inertia_yy_kg_m2", defaults.inertia_yy_kg_m2);
  c.inertia_zz_kg_m2 = params.number("inertia_zz_kg_m2", defaults.inertia_zz_kg_m2);
  c.stiffness_z_n_per_m = params.number("stiffness_z_n_per_m", defaults.stiffness_z_n_per_m);
  c.stiffness_theta_x_n_m_per_rad =
      params.number("stiffness_theta_x_n_m_per_rad", defaults.stiffness_theta_x_n_m_per_rad);
  c.stiffness_theta_y_n_m_per_rad =
      params.number("stiffness_theta_y_n_m_per_rad", defaults.stiffness_theta_y_n_m_per_rad);
  c.b_planar_acc_per_a =
      read_input_matrix(params, "b_planar_acc_per_a", defaults.b_planar_acc_per_a, "x, y and theta_z");
  c.b_vertical_acc_per_a =
      read_input_matrix(params, "b_vertical_acc_per_a", defaults.b_vertical_acc_per_a, "z, theta_x and theta_y");
  plants::read_initial_condition(params, c.initial, c.initial_velocity);
  plants::read_numbers_into(params, "disturbance_wrench", c.disturbance_wrench);

  const auto positive = [&](double value, std::string_view key, const char* unit) {
    params.check(value > 0.0 && std::isfinite(value), key,
                 std::string("must be > 0 ") + unit + ", got " + number_text(value));
  };
  const auto non_negative = [&](double value, std::string_view key, const char* unit) {
    params.check(value >= 0.0 && std::isfinite(value), key,
                 std::string("must be >= 0 ") + unit + " (0 = no spring), got " + number_text(value));
  };
  positive(c.mass_kg, "mass_kg", "kg");
  positive(c.inertia_xx_kg_m2, "inertia_xx_kg_m2", "kg*m^2");
  positive(c.inertia_yy_kg_m2, "inertia_yy_kg_m2", "kg*m^2");
  positive(c.inertia_zz_kg_m2, "inertia_zz_kg_m2", "kg*m^2");
  non_negative(c.stiffness_z_n_per_m, "stiffness_z_n_per_m", "N/m");
  non_negative(c.stiffness_theta_x_n_m_per_rad, "stiffness_theta_x_n_m_per_rad", "N*m/rad");
  non_negative(c.stiffness_theta_y_n_m_per_rad, "stiffness_theta_y_n_m_per_rad", "N*m/rad");
  for (const auto& [key, values] : {std::pair<const char*, const std::array<double, 6>*>{"initial", &c.initial},
                                    {"initial_velocity", &c.initial_velocity},
                                    {"disturbance_wrench", &c.disturbance_wrench}}) {
    for (double v : *values) {
      if (!std::isfinite(v)) {
        params.fail(key, "must be finite");
        break;
      }
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void Maglev6::apply(const Maglev6Config& config) {
  config_ = config;
  inverse_inertia_ = {1.0 / config.mass_kg,          1.0 / config.mass_kg,          1.0 / config.inertia_zz_kg_m2,
                      1.0 / config.mass_kg,          1.0 / config.inertia_xx_kg_m2, 1.0 / config.inertia_yy_kg_m2};
  omega_ = {0.0,
            0.0,
            0.0,
            std::sqrt(config.stiffness_z_n_per_m / config.mass_kg),
            std::sqrt(config.stiffness_theta_x_n_m_per_rad / config.inertia_xx_kg_m2),
            std::sqrt(config.stiffness_theta_y_n_m_per_rad / config.inertia_yy_kg_m2)};
  reset();
}

void Maglev6::reset() noexcept {
  plants::write_initial_state(config_.initial, config_.initial_velocity, x_.data());
}

void Maglev6::forcing(const double* u, std::array<double, kAxes>& acceleration) const noexcept {
  // eq. 11 form: the quadrature currents drive the planar axes, the direct currents the
  // vertical ones (eq. 7: i_Q horizontal force, i_D vertical force).
  for (int i = 0; i < 3; ++i) {
    double planar = 0.0;
    double vertical = 0.0;
    for (int j = 0; j < 3; ++j) {
      planar += config_.b_planar_acc_per_a(i, j) * u[kIqA + static_cast<std::size_t>(j)];
      vertical += config_.b_vertical_acc_per_a(i, j) * u[kIdA + static_cast<std::size_t>(j)];
    }
    const auto p = static_cast<std::size_t>(i);
    acceleration[p] = planar + config_.disturbance_wrench[p] * inverse_inertia_[p];
    acceleration[3 + p] = vertical + config_.disturbance_wrench[3 + p] * inverse_inertia_[3 + p];
  }
}

void Maglev6::integrate(double dt_s, const double* x, const std::array<double, kAxes>& acceleration,
                        double* x_next) const noexcept {
  // Inputs are held over dt (ZOH), so each axis p'' = -w^2 p + a has the exact solution
  //   w = 0:  p += v dt + a dt^2/2,                   v += a dt
  //   w > 0:  e = p - a/w^2;  p = a/w^2 + e cos(w dt) + (v/w) sin(w dt),
  //           v = -e w sin(w dt) + v cos(w dt)
  // (eqs. 2-5): one 10 ms step equals ten 1 ms steps up to rounding.
  for (std::size_t i = 0; i < kAxes; ++i) {
    const double p = x[i];
    const double v = x[kAxes + i];
    const double a = acceleration[i];
    const double w = omega_[i];
    if (w == 0.0) {
      x_next[i] = p + v * dt_s + 0.5 * a * dt_s * dt_s;
      x_next[kAxes + i] = v + a * dt_s;
    } else {
      const double c = std::cos(w * dt_s);
      const double s = std::sin(w * dt_s);
      const double equilibrium = a / (w * w);
      const double e = p - equilibrium;
      x_next[i] = equilibrium + e * c + v / w * s;
      x_next[kAxes + i] = -e * w * s + v * c;
    }
  }
}

void Maglev6::advance(double dt_s, const double* u) noexcept {
  std::array<double, kAxes> acceleration{};
  forcing(u, acceleration);
  std::array<double, kStateSize> next{};
  integrate(dt_s, x_.data(), acceleration, next.data());
  x_ = next;
}

void Maglev6::output(double* y) const noexcept {
  for (std::size_t i = 0; i < kAxes; ++i) y[i] = x_[i];
}

void Maglev6::state(double* x) const noexcept {
  for (std::size_t i = 0; i < kStateSize; ++i) x[i] = x_[i];
}

void Maglev6::propagate(double dt_s, const double* x, const double* u, double* x_next) const noexcept {
  std::array<double, kAxes> acceleration{};
  forcing(u, acceleration);
  integrate(dt_s, x, acceleration, x_next);
}

bool Maglev6::process_jacobian(double dt_s, const double* /*x*/, const double* /*u*/, double* F) const noexcept {
  // The model is linear: F = e^{A dt}, per axis [[cos, sin/w], [-w sin, cos]] (-> [[1, dt], [0, 1]]).
  for (std::size_t k = 0; k < kStateSize * kStateSize; ++k) F[k] = 0.0;
  for (std::size_t i = 0; i < kAxes; ++i) {
    const double w = omega_[i];
    const std::size_t p = i;
    const std::size_t v = kAxes + i;
    if (w == 0.0) {
      F[p * kStateSize + p] = 1.0;
      F[p * kStateSize + v] = dt_s;
      F[v * kStateSize + v] = 1.0;
    } else {
      const double c = std::cos(w * dt_s);
      const double s = std::sin(w * dt_s);
      F[p * kStateSize + p] = c;
      F[p * kStateSize + v] = s / w;
      F[v * kStateSize + p] = -w * s;
      F[v * kStateSize + v] = c;
    }
  }
  return true;
}

Maglev6::Mode Maglev6::planar_mode() const {
  Mode m;
  m.a.topRightCorner<3, 3>().setIdentity();
  m.b.bottomRows<3>() = config_.b_planar_acc_per_a;
  m.c.leftCols<3>().setIdentity();
  return m;
}

Maglev6::Mode Maglev6::vertical_mode() const {
  Mode m;
  m.a.topRightCorner<3, 3>().setIdentity();
  for (int i = 0; i < 3; ++i) {
    const double w = omega_[3 + static_cast<std::size_t>(i)];
    m.a(3 + i, i) = -w * w;
  }
  m.b.bottomRows<3>() = config_.b_vertical_acc_per_a;
  m.c.leftCols<3>().setIdentity();
  return m;
}

void Maglev6::describe(Json& out) const {
  out["mass_kg"] = config_.mass_kg;
  out["inertia_xx_kg_m2"] = config_.inertia_xx_kg_m2;
  out["inertia_yy_kg_m2"] = config_.inertia_yy_kg_m2;
  out["inertia_zz_kg_m2"] = config_.inertia_zz_kg_m2;
  out["stiffness_z_n_per_m"] = config_.stiffness_z_n_per_m;
  out["stiffness_theta_x_n_m_per_rad"] = config_.stiffness_theta_x_n_m_per_rad;
  out["stiffness_theta_y_n_m_per_rad"] = config_.stiffness_theta_y_n_m_per_rad;
  out["b_planar_acc_per_a"] = matrix_json(config_.b_planar_acc_per_a);
  out["b_vertical_acc_per_a"] = matrix_json(config_.b_vertical_acc_per_a);
  // Force and torque per ampere (diag(M, M, Izz) B_planar etc.): what each motor produces.
  const Eigen::Vector3d planar_inertia(config_.mass_kg, config_.mass_kg, config_.inertia_zz_kg_m2);
  const Eigen::Vector3d vertical_inertia(config_.mass_kg, config_.inertia_xx_kg_m2, config_.inertia_yy_kg_m2);
  out["planar_wrench_per_a"] = matrix_json(planar_inertia.asDiagonal() * config_.b_planar_acc_per_a);
  out["vertical_wrench_per_a"] = matrix_json(vertical_inertia.asDiagonal() * config_.b_vertical_acc_per_a);
  Json natural = Json::object();
  const char* names[] = {"z", "theta_x", "theta_y"};
  for (std::size_t i = 0; i < 3; ++i) {
    Json axis = Json::object();
    axis["rad_s"] = omega_[3 + i];
    axis["hz"] = omega_[3 + i] / (2.0 * std::numbers::pi);
    natural[names[i]] = std::move(axis);
  }
  out["vertical_natural_frequency"] = std::move(natural);
  const auto mode_json = [](const Mode& mode, const char* states, const char* inputs) {
    Json m = Json::object();
    m["states"] = states;
    m["inputs"] = inputs;
    m["A"] = matrix_json(mode.a);
    m["B"] = matrix_json(mode.b);
    return m;
  };
  Json modes = Json::object();
  modes["planar"] = mode_json(planar_mode(), "x, y, theta_z, vx, vy, omega_z", "iq_a, iq_b, iq_c");
  modes["vertical"] = mode_json(vertical_mode(), "z, theta_x, theta_y, vz, omega_x, omega_y", "id_a, id_b, id_c");
  out["continuous_modes"] = std::move(modes);
  plants::describe_initial_condition(out, config_.initial, config_.initial_velocity);
  out["disturbance_wrench"] =
      std::vector<double>(config_.disturbance_wrench.begin(), config_.disturbance_wrench.end());
  out["integration"] = "exact zero-order hold per axis (double integrator or undamped spring-mass)";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"mass_kg", "number", "1.52", "moving mass M (the paper's), > 0"},
    {"inertia_xx_kg_m2", "number", "0.0037", "principal inertia about x, > 0"},
    {"inertia_yy_kg_m2", "number", "0.0019", "principal inertia about y, > 0"},
    {"inertia_zz_kg_m2", "number", "0.0022", "principal inertia about z, > 0"},
    {"stiffness_z_n_per_m", "number", "620", "air-bearing stiffness Kz, >= 0"},
    {"stiffness_theta_x_n_m_per_rad", "number", "65", "torsional stiffness about x (paper K_theta), >= 0"},
    {"stiffness_theta_y_n_m_per_rad", "number", "87", "torsional stiffness about y (paper K_psi), >= 0"},
    {"b_planar_acc_per_a", "list<number>[9]", "surrogate fitted to eq. 17 (README)",
     "row-major 3x3: rows x'' [m/s^2], y'' [m/s^2], theta_z'' [rad/s^2] per ampere of iq_a, iq_b, iq_c; invertible"},
    {"b_vertical_acc_per_a", "list<number>[9]", "surrogate fitted to eq. 19 (README)",
     "row-major 3x3: rows z'' [m/s^2], theta_x'' [rad/s^2], theta_y'' [rad/s^2] per ampere of id_a, id_b, id_c; "
     "invertible"},
    {"initial", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "initial x, y [m], theta_z [rad], z [m], theta_x, theta_y [rad]"},
    {"initial_velocity", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "initial rates [m/s, rad/s] in the same order"},
    {"disturbance_wrench", "list<number>[6]", "[0, 0, 0, 0, 0, 0]",
     "constant disturbance fx, fy [N], tz [N*m], fz [N], tx, ty [N*m] (e.g. cable forces)"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::Maglev6, "plant.maglev6", lode::PluginKind::plant, "0.1.0",
            "Six-axis maglev platen on air bearings (Silva-Rivas & Kim 2013, eqs. 2-5) with the "
            "surrogate input matrices fitted to its printed LQ gains; exact ZOH; also a ProcessModel",
            lode::plugins::kParams, lode::kNoPorts)
