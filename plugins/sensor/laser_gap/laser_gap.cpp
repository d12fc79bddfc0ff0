#include "laser_gap.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <set>
#include <string>
#include <utility>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace {

/// H of the channels at the zero pose: row i = [1, y_i, -x_i] (times the sensitivity).
Eigen::MatrixXd geometry_matrix(const std::vector<LaserSpot>& spots) {
  Eigen::MatrixXd h(static_cast<Eigen::Index>(spots.size()), 3);
  for (std::size_t i = 0; i < spots.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    h(r, 0) = 1.0;
    h(r, 1) = spots[i].y_m;
    h(r, 2) = -spots[i].x_m;
  }
  return h;
}

/// What the spots see: the vertical pose, before and after the spots are known.
Elements vertical_pose() { return {{"z", "m"}, {"theta_x", "rad"}, {"theta_y", "rad"}}; }

}  // namespace

LaserGap::LaserGap() { declare_measurement_elements(vertical_pose(), {}); }

Status LaserGap::configure(Params& params) {
  const double sensitivity = params.number("sensitivity_v_per_m");
  params.check(std::isfinite(sensitivity) && sensitivity != 0.0, "sensitivity_v_per_m",
               "must be non-zero and finite (its sign sets the direction), got " + number_text(sensitivity));
  std::vector<LaserSpot> spots;
  std::vector<Params> items = params.items("sensors");
  if (items.size() < 3 || items.size() > kMaxSensors) {
    params.fail("sensors", "needs 3 to " + std::to_string(kMaxSensors) + " sensors to resolve z, theta_x and theta_y, got " +
                               std::to_string(items.size()));
  }
  std::set<std::string> names;
  for (Params& item : items) {
    LaserSpot s;
    s.name = item.text("name");
    s.x_m = item.number("x_m");
    s.y_m = item.number("y_m");
    s.offset_v = item.number("offset_v", 0.0);
    if (!s.name.empty() && !names.insert(s.name).second) item.fail("name", "duplicate sensor name '" + s.name + "'");
    if (s.name.empty()) item.fail("name", "must not be empty");
    spots.push_back(s);
  }
  if (params.ok()) {
    // z, theta_x, theta_y are observable only when the spots are not on one line.
    const Eigen::MatrixXd h = geometry_matrix(spots);
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(h);
    const double smallest = svd.singularValues()(2);
    const double largest = svd.singularValues()(0);
    if (!(smallest > 1e-9 * largest)) {
      params.fail("sensors", "the spots lie on one line (or coincide): z, theta_x and theta_y cannot all be "
                             "resolved (singular values of [1, y, -x]: " + number_text(largest) + ", " +
                             number_text(svd.singularValues()(1)) + ", " + number_text(smallest) + ")");
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");
  apply(std::move(spots), sensitivity);
  return Status::ok();
}

void LaserGap::apply(std::vector<LaserSpot> spots, double sensitivity_v_per_m) {
  spots_ = std::move(spots);
  sensitivity_v_per_m_ = sensitivity_v_per_m;
  Elements channels;
  for (const LaserSpot& s : spots_) channels.push_back({s.name, "V"});
  declare_measurement_elements(vertical_pose(), std::move(channels));
}

void LaserGap::evaluate(const double* state, double* y) const noexcept {
  const double cx = std::cos(state[kThetaX]);
  const double sx = std::sin(state[kThetaX]);
  const double sy = std::sin(state[kThetaY]);
  for (std::size_t i = 0; i < spots_.size(); ++i) {
    const LaserSpot& s = spots_[i];
    const double displacement = state[kZ] + s.y_m * sx - s.x_m * cx * sy;
    y[i] = s.offset_v + sensitivity_v_per_m_ * displacement;
  }
}

void LaserGap::jacobian(const double* state, double* y, double* H) const noexcept {
  evaluate(state, y);
  const double cx = std::cos(state[kThetaX]);
  const double sx = std::sin(state[kThetaX]);
  const double cy = std::cos(state[kThetaY]);
  const double sy = std::sin(state[kThetaY]);
  for (std::size_t i = 0; i < spots_.size(); ++i) {
    const LaserSpot& s = spots_[i];
    double* row = H + kStateSize * i;
    row[kZ] = sensitivity_v_per_m_;
    row[kThetaX] = sensitivity_v_per_m_ * (s.y_m * cx + s.x_m * sx * sy);
    row[kThetaY] = -sensitivity_v_per_m_ * s.x_m * cx * cy;
  }
}

std::vector<double> LaserGap::pose_noise_per_volt() const {
  const Eigen::MatrixXd h = sensitivity_v_per_m_ * geometry_matrix(spots_);
  const Eigen::Matrix3d covariance = (h.transpose() * h).inverse();
  return {std::sqrt(covariance(0, 0)), std::sqrt(covariance(1, 1)), std::sqrt(covariance(2, 2))};
}

void LaserGap::describe(Json& out) const {
  out["sensitivity_v_per_m"] = sensitivity_v_per_m_;
  Json spots = Json::array();
  for (const LaserSpot& s : spots_) {
    Json j = Json::object();
    j["name"] = s.name;
    j["x_m"] = s.x_m;
    j["y_m"] = s.y_m;
    j["offset_v"] = s.offset_v;
    spots.push(std::move(j));
  }
  out["sensors"] = std::move(spots);
  out["measurement"] = "v_i = offset_v + sensitivity (z + y_i sin(theta_x) - x_i cos(theta_x) sin(theta_y))";
  // How a white voltage noise maps into the least-squares pose: per volt of channel noise.
  const std::vector<double> noise = pose_noise_per_volt();
  Json per_volt = Json::object();
  per_volt["z_m"] = noise[0];
  per_volt["theta_x_rad"] = noise[1];
  per_volt["theta_y_rad"] = noise[2];
  out["pose_noise_std_per_volt_of_channel_noise"] = std::move(per_volt);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"sensitivity_v_per_m", "number", nullptr, "output volts per metre of displacement, non-zero (sign = direction)"},
    {"sensors", "list<map>", nullptr,
     "3..8 entries {name, x_m, y_m, offset_v}: channel name, body-frame spot position [m], output at zero "
     "displacement [V] (default 0); spots not all on one line"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::LaserGap, "sensor.laser_gap", lode::PluginKind::sensor, "0.1.0",
            "Laser distance sensors on the platen: z, theta_x, theta_y from three or more spots "
            "(Silva-Rivas & Kim 2013 vertical sensing, geometry from configuration)",
            lode::plugins::kParams, lode::kNoPorts)
