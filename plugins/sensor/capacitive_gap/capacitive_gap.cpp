#include "capacitive_gap.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <set>
#include <utility>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace {

/// R_BF = Rz(psi) Ry(theta) Rx(phi) and its partial derivatives (z-y-x, as plant.rigid_body6).
struct Rotation {
  Eigen::Matrix3d r;
  Eigen::Matrix3d d_phi;
  Eigen::Matrix3d d_theta;
  Eigen::Matrix3d d_psi;
};

Rotation rotation_of(double phi, double theta, double psi, bool with_derivatives) noexcept {
  const double cf = std::cos(phi), sf = std::sin(phi);
  const double ct = std::cos(theta), st = std::sin(theta);
  const double cp = std::cos(psi), sp = std::sin(psi);
  Eigen::Matrix3d rx, ry, rz;
  rx << 1, 0, 0, 0, cf, -sf, 0, sf, cf;
  ry << ct, 0, st, 0, 1, 0, -st, 0, ct;
  rz << cp, -sp, 0, sp, cp, 0, 0, 0, 1;
  Rotation out;
  out.r = rz * ry * rx;
  if (with_derivatives) {
    Eigen::Matrix3d drx, dry, drz;
    drx << 0, 0, 0, 0, -sf, -cf, 0, cf, -sf;
    dry << -st, 0, ct, 0, 0, 0, -ct, 0, -st;
    drz << -sp, -cp, 0, cp, -sp, 0, 0, 0, 0;
    out.d_phi = rz * ry * drx;
    out.d_theta = rz * dry * rx;
    out.d_psi = drz * ry * rx;
  }
  return out;
}

}  // namespace

std::vector<GapProbe> default_gap_probes() {
  const double radius = 0.05;  // z probes on a 50 mm circle
  const double below = -0.01;  // targets on the bottom face, 10 mm below the centre of gravity
  const double half_span = 0.04;
  const double sqrt3_2 = std::sqrt(3.0) / 2.0;
  return {
      {"z1", Eigen::Vector3d(radius, 0.0, below), Eigen::Vector3d::UnitZ()},
      {"z2", Eigen::Vector3d(-0.5 * radius, sqrt3_2 * radius, below), Eigen::Vector3d::UnitZ()},
      {"z3", Eigen::Vector3d(-0.5 * radius, -sqrt3_2 * radius, below), Eigen::Vector3d::UnitZ()},
      {"x1", Eigen::Vector3d(-radius, half_span, 0.0), Eigen::Vector3d::UnitX()},
      {"x2", Eigen::Vector3d(-radius, -half_span, 0.0), Eigen::Vector3d::UnitX()},
      {"y1", Eigen::Vector3d(0.0, -radius, 0.0), Eigen::Vector3d::UnitY()},
  };
}

CapacitiveGap::CapacitiveGap() {
  CapacitiveGapConfig c;
  c.probes = default_gap_probes();
  apply(c);
}

Status CapacitiveGap::configure(Params& params) {
  CapacitiveGapConfig c;
  c.nominal_gap_m = params.number("nominal_gap_m", 1e-3);
  c.zero_gap_m = params.number("zero_gap_m", 1e-3);
  c.sensitivity_v_per_m = params.number("sensitivity_v_per_m", 2e4);
  params.check(c.nominal_gap_m > 0.0, "nominal_gap_m", "must be > 0 m, got " + number_text(c.nominal_gap_m));
  params.check(c.sensitivity_v_per_m != 0.0 && std::isfinite(c.sensitivity_v_per_m), "sensitivity_v_per_m",
               "must be non-zero, got " + number_text(c.sensitivity_v_per_m));

  if (params.has("probes")) {
    std::set<std::string> names;
    for (Params& item : params.items("probes")) {
      GapProbe probe;
      probe.name = item.text("name");
      const std::vector<double> target = item.numbers("target_m", 3);
      const std::vector<double> axis = item.numbers("axis", 3);
      probe.target_m = Eigen::Vector3d(target[0], target[1], target[2]);
      const Eigen::Vector3d n(axis[0], axis[1], axis[2]);
      if (!(n.norm() > 0.0)) {
        item.fail("axis", "the measuring axis must be a non-zero vector");
      } else {
        probe.axis = n.normalized();
      }
      if (!probe.name.empty() && !names.insert(probe.name).second) {
        item.fail("name", "duplicate probe name '" + probe.name + "'");
      }
      c.probes.push_back(probe);
    }
    params.check(!c.probes.empty() && c.probes.size() <= kMaxProbes, "probes",
                 "needs 1 to " + std::to_string(kMaxProbes) + " probes, got " + std::to_string(c.probes.size()));
  } else {
    c.probes = default_gap_probes();
  }
  if (!params.ok()) return Status::error("invalid parameters");
  apply(c);
  return Status::ok();
}

void CapacitiveGap::apply(const CapacitiveGapConfig& config) {
  config_ = config;
  face_m_.clear();
  Elements channels;
  for (const GapProbe& probe : config_.probes) {
    face_m_.push_back(probe.target_m - config_.nominal_gap_m * probe.axis);
    channels.push_back({probe.name, "V"});
  }
  declare_measurement_elements({{"x", "m"}, {"y", "m"}, {"z", "m"}, {"phi", "rad"}, {"theta", "rad"}, {"psi", "rad"}},
                               std::move(channels));
}

void CapacitiveGap::gaps(const double* state, double* gap_m) const noexcept {
  const Rotation rot = rotation_of(state[3], state[4], state[5], false);
  const Eigen::Vector3d p(state[0], state[1], state[2]);
  for (std::size_t i = 0; i < config_.probes.size(); ++i) {
    const GapProbe& probe = config_.probes[i];
    const Eigen::Vector3d normal = rot.r * probe.axis;
    // (R r - r) is formed first so the 1 mm offset does not swamp a nanometre displacement.
    const Eigen::Vector3d offset = p + (rot.r * probe.target_m - probe.target_m) + config_.nominal_gap_m * probe.axis;
    gap_m[i] = offset.dot(normal) / probe.axis.dot(normal);
  }
}

void CapacitiveGap::evaluate(const double* state, double* y) const noexcept {
  gaps(state, y);
  for (std::size_t i = 0; i < config_.probes.size(); ++i) {
    y[i] = config_.sensitivity_v_per_m * (y[i] - config_.zero_gap_m);
  }
}

void CapacitiveGap::jacobian(const double* state, double* y, double* H) const noexcept {
  const Rotation rot = rotation_of(state[3], state[4], state[5], true);
  const Eigen::Vector3d p(state[0], state[1], state[2]);
  const double k = config_.sensitivity_v_per_m;
  for (std::size_t i = 0; i < config_.probes.size(); ++i) {
    const GapProbe& probe = config_.probes[i];
    const Eigen::Vector3d normal = rot.r * probe.axis;
    const Eigen::Vector3d offset = p + (rot.r * probe.target_m - probe.target_m) + config_.nominal_gap_m * probe.axis;
    const double numerator = offset.dot(normal);
    const double denominator = probe.axis.dot(normal);
    const double gap = numerator / denominator;
    y[i] = k * (gap - config_.zero_gap_m);
    double* row = H + i * kStates;
    // d/dp: normal / denominator.
    for (std::size_t j = 0; j < 3; ++j) row[j] = k * normal(static_cast<Eigen::Index>(j)) / denominator;
    // d/dangle: (dN - g dD) / D with dN = (dR r).(R n) + offset.(dR n), dD = n.(dR n).
    const Eigen::Matrix3d* partials[3] = {&rot.d_phi, &rot.d_theta, &rot.d_psi};
    for (std::size_t j = 0; j < 3; ++j) {
      const Eigen::Matrix3d& dr = *partials[j];
      const Eigen::Vector3d d_normal = dr * probe.axis;
      const double d_numerator = (dr * probe.target_m).dot(normal) + offset.dot(d_normal);
      const double d_denominator = probe.axis.dot(d_normal);
      row[3 + j] = k * (d_numerator - gap * d_denominator) / denominator;
    }
  }
}

void CapacitiveGap::describe(Json& out) const {
  out["nominal_gap_m"] = config_.nominal_gap_m;
  out["zero_gap_m"] = config_.zero_gap_m;
  out["sensitivity_v_per_m"] = config_.sensitivity_v_per_m;
  out["equation"] = "g_i = (p + R r_i - s_i).(R n_i) / (n_i.R n_i), s_i = r_i - g0 n_i; v_i = k (g_i - zero_gap)";
  Json probes = Json::array();
  for (const GapProbe& probe : config_.probes) {
    Json j = Json::object();
    j["name"] = probe.name;
    j["target_m"] = std::vector<double>{probe.target_m(0), probe.target_m(1), probe.target_m(2)};
    j["axis"] = std::vector<double>{probe.axis(0), probe.axis(1), probe.axis(2)};
    probes.push(std::move(j));
  }
  out["probes"] = std::move(probes);
  // Pose -> volts at home, so a reader sees the lever arms (V/m, V/rad).
  const double home[kStates] = {};
  std::vector<double> y(config_.probes.size());
  std::vector<double> h(config_.probes.size() * kStates);
  jacobian(home, y.data(), h.data());
  Json rows = Json::array();
  for (std::size_t i = 0; i < config_.probes.size(); ++i) {
    rows.push(Json(std::vector<double>(h.begin() + static_cast<std::ptrdiff_t>(i * kStates),
                                       h.begin() + static_cast<std::ptrdiff_t>((i + 1) * kStates))));
  }
  out["jacobian_at_home_v_per_m_or_rad"] = std::move(rows);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"probes", "list<map>", "3-2-1 layout (z1 z2 z3 x1 x2 y1)",
     "{name, target_m: [x, y, z] body point of the flat target [m], axis: [nx, ny, nz] measuring axis}, 1 ... 16"},
    {"nominal_gap_m", "number", "1e-3", "gap at home (the paper's 1 mm), > 0"},
    {"zero_gap_m", "number", "1e-3", "gap that reads 0 V (centre of the 500-1500 um range)"},
    {"sensitivity_v_per_m", "number", "2e4", "probe + amplifier gain (10 V per 500 um), non-zero"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::CapacitiveGap, "sensor.capacitive_gap", lode::PluginKind::sensor, "0.1.0",
            "Capacitive gap probes on flat targets of a 6-DOF body (Gutierrez & Li 2024), analytic Jacobian",
            lode::plugins::kParams, lode::kNoPorts)
