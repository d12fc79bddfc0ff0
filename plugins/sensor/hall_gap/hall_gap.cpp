#include "hall_gap.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "lode/sdk/plugin.hpp"

namespace lode::plugins {

namespace {

/// d_hall = d within what eq. 14 can report (C_H clamped to its range), in m. Here rather
/// than in evaluate() alone so that jacobian() inlines it: an exported member would be called
/// through the PLT on every EKF step.
double reported_gap_m(double distance_mm, double nearest_mm, double farthest_mm) noexcept {
  return 1e-3 * std::clamp(distance_mm, nearest_mm, farthest_mm);
}

}  // namespace

HallGap::HallGap() { apply(hall::Conversion::paper(), Output::hall_voltage, "hall"); }

Status HallGap::configure(Params& params) {
  const std::string output = params.choice("output", {"hall_voltage", "gap"}, std::string_view("hall_voltage"));
  const Output which = output == "gap" ? Output::gap : Output::hall_voltage;
  const std::string channel = params.text("channel", which == Output::gap ? "gap" : "hall");
  const hall::Conversion conversion = hall::read_conversion(params);
  params.check(!channel.empty(), "channel", "the channel name must not be empty");
  if (!params.ok()) return Status::error("invalid parameters");
  apply(conversion, which, channel);
  return Status::ok();
}

void HallGap::apply(const hall::Conversion& conversion, Output output, const std::string& channel) {
  conversion_ = conversion;
  output_ = output;
  nearest_mm_ = conversion_.nearest_mm();
  farthest_mm_ = conversion_.farthest_mm();
  if (output_ == Output::hall_voltage) {
    declare_measurement_elements({{"gap", "m"}, {"coil_voltage", "V"}}, {{channel, "V"}});
  } else {
    declare_measurement_elements({{"gap", "m"}}, {{channel, "m"}});
  }
}

void HallGap::evaluate(const double* state, double* y) const noexcept {
  const double distance_mm = 1e3 * state[kGap];
  if (output_ == Output::gap) {
    y[0] = reported_gap_m(distance_mm, nearest_mm_, farthest_mm_);
    return;
  }
  const double c_h = conversion_.compensated_for_distance(distance_mm, nearest_mm_, farthest_mm_);
  y[0] = c_h + conversion_.coil_v.value(state[kCoilVoltage]);  // eq. 15 solved for v_hall
}

void HallGap::evaluate_points(const double* states, std::size_t stride, std::size_t count,
                              double* y) const noexcept {
  if (output_ == Output::gap) {
    for (std::size_t i = 0; i < count; ++i)
      y[i] = reported_gap_m(1e3 * states[i * stride + kGap], nearest_mm_, farthest_mm_);
    return;
  }
  MeasurementModel::evaluate_points(states, stride, count, y);  // point by point
}

void HallGap::jacobian(const double* state, double* y, double* H) const noexcept {
  const double distance_mm = 1e3 * state[kGap];
  const bool inside = distance_mm > nearest_mm_ && distance_mm < farthest_mm_;
  if (output_ == Output::gap) {
    y[0] = reported_gap_m(distance_mm, nearest_mm_, farthest_mm_);
    H[kGap] = inside ? 1.0 : 0.0;
    return;
  }
  evaluate(state, y);
  // dC_H/dgap = 1000 / M_H'(C_H) (inverse function rule; M_H' < 0 on the range).
  const double c_h = conversion_.compensated_for_distance(distance_mm, nearest_mm_, farthest_mm_);
  H[kGap] = inside ? 1e3 / conversion_.distance_mm.slope(c_h) : 0.0;
  H[kCoilVoltage] = conversion_.coil_v.slope(state[kCoilVoltage]);
}

void HallGap::describe(Json& out) const {
  out["output"] = output_ == Output::gap ? "gap (y = d, the direct distance of eq. 14)"
                                         : "hall_voltage (forward eq. 14-16)";
  out["coil_polynomial_v"] = conversion_.coil_v.coefficients();
  out["distance_polynomial_mm"] = conversion_.distance_mm.coefficients();
  out["compensated_range_v"] = std::vector<double>{conversion_.compensated_min_v, conversion_.compensated_max_v};
  out["gap_range_m"] = std::vector<double>{1e-3 * conversion_.nearest_mm(), 1e-3 * conversion_.farthest_mm()};
  out["max_slope_mm_per_v"] = conversion_.max_distance_slope();
  // The characteristic at C_H = 0, 0.1, ..., 0.8 V and the sensitivity an ADC LSB maps to.
  Json table = Json::array();
  for (int k = 0; k <= 8; ++k) {
    const double c_h = conversion_.compensated_min_v +
                       (conversion_.compensated_max_v - conversion_.compensated_min_v) * k / 8.0;
    Json row = Json::object();
    row["compensated_v"] = c_h;
    row["distance_mm"] = conversion_.distance_mm.value(c_h);
    row["slope_mm_per_v"] = conversion_.distance_mm.slope(c_h);
    table.push(std::move(row));
  }
  out["characteristic"] = std::move(table);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"output", "text", "hall_voltage",
     "hall_voltage: the Hall output [V] for (gap, coil_voltage) (forward eq. 14-16, for io.sim); "
     "gap: the direct distance d_hall = d [m] (eq. 32 y = d, for an estimator fed by estimator.hall_direct)"},
    {"channel", "text", "hall (hall_voltage) / gap (gap)", "name of the one channel"},
    {"coil_polynomial_v", "list<number>", "[1.299e-6, 9.05e-5, 2.544]",
     "eq. 15: quiescent + coil-induced Hall voltage vs coil voltage v, descending powers [V/V^2, V/V, V]"},
    {"distance_polynomial_mm", "list<number>", "[-563.9, 1351.6, -1284.2, 633.1, -183.9, 46.9]",
     "eq. 16: M_H, distance [mm] vs compensated Hall voltage C_H [V], descending powers"},
    {"compensated_range_v", "list<number>[2]", "[0, 0.8]",
     "valid C_H range [V]; M_H must decrease strictly on it; C_H is clamped to it"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::HallGap, "sensor.hall_gap", lode::PluginKind::sensor, "0.1.0",
            "Hall-sensor gap measurement of Sensors 2016: eq. 14-16 with the coil compensation (bracketed eq. 15)",
            lode::plugins::kParams, lode::kNoPorts)
