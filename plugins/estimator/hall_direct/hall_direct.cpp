#include "hall_direct.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace {

std::string names_of(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out;
}

/// The element called `name` (unit-compatible with `unit`), else the only element.
bool find_element(const Elements& source, const std::string& name, const std::string& unit, std::size_t& index,
                  std::string& why) {
  for (std::size_t i = 0; i < source.size(); ++i) {
    if (source[i].name != name) continue;
    if (!units_compatible(source[i].unit, unit)) {
      why = "'" + name + "' is in " + source[i].unit + ", expected " + unit;
      return false;
    }
    index = i;
    return true;
  }
  if (source.size() == 1 && units_compatible(source[0].unit, unit)) {
    index = 0;
    return true;
  }
  why = "no element '" + name + "' [" + unit + "] among " + names_of(source);
  return false;
}

}  // namespace

Status HallDirect::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  channel_ = params.text("channel", "hall");
  output_name_ = params.text("output_name", "gap");
  conversion_ = hall::read_conversion(params);
  params.check(!output_name_.empty(), "output_name", "must not be empty");

  ctx.declare_input(signals_, "signals", {}, true);
  ctx.declare_input(coil_voltage_, "coil_voltage", {}, false);
  std::string why;
  if (const Elements* source = ctx.input_source("signals"); source == nullptr) {
    params.fail("inputs", "the signals input must be connected to an output carrying the Hall voltage '" +
                              channel_ + "' [V]");
  } else if (!find_element(*source, channel_, "V", hall_index_, why)) {
    params.fail("inputs", "signals: " + why);
  }
  use_coil_voltage_ = false;
  if (const Elements* source = ctx.input_source("coil_voltage"); source != nullptr) {
    if (!find_element(*source, "coil_voltage", "V", coil_index_, why)) {
      params.fail("inputs", "coil_voltage: " + why);
    } else {
      use_coil_voltage_ = true;
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");
  ctx.declare_output(gap_, "gap", {{output_name_, "m"}});
  ctx.declare_output(compensated_, "compensated", {{"compensated", "V"}});
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status HallDirect::activate() {
  clamps_.store(0, std::memory_order_relaxed);
  gap_[0] = 1e-3 * conversion_.farthest_mm();
  compensated_[0] = conversion_.compensated_min_v;
  return Status::ok();
}

StepStatus HallDirect::step(const Tick& /*tick*/) noexcept {
  const double hall_v = signals_[hall_index_];
  const double coil_v = use_coil_voltage_ ? coil_voltage_[coil_index_] : 0.0;
  if (!std::isfinite(hall_v) || !std::isfinite(coil_v)) return fault("non-finite Hall or coil voltage");
  bool clamped = false;
  gap_[0] = conversion_.direct_gap_m(hall_v, coil_v, clamped);  // eq. 14-16
  compensated_[0] = conversion_.compensated_v(hall_v, coil_v);
  if (clamped) clamps_.fetch_add(1, std::memory_order_relaxed);
  return StepStatus::ok;
}

void HallDirect::describe(Json& out) const {
  out["channel"] = channel_;
  out["coil_compensation"] = use_coil_voltage_ ? "coil_voltage input" : "none connected (v = 0)";
  out["coil_polynomial_v"] = conversion_.coil_v.coefficients();
  out["distance_polynomial_mm"] = conversion_.distance_mm.coefficients();
  out["compensated_range_v"] = std::vector<double>{conversion_.compensated_min_v, conversion_.compensated_max_v};
  out["gap_range_m"] = std::vector<double>{1e-3 * conversion_.nearest_mm(), 1e-3 * conversion_.farthest_mm()};
  // What one volt (and one 12-bit LSB of 3.3 V) of Hall error costs in distance, across the range.
  Json sensitivity = Json::array();
  for (double c_h : {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8}) {
    Json row = Json::object();
    row["compensated_v"] = c_h;
    row["gap_m"] = 1e-3 * conversion_.distance_mm.value(c_h);
    row["slope_m_per_v"] = 1e-3 * conversion_.distance_mm.slope(c_h);
    row["lsb_3v3_12bit_m"] = std::abs(1e-3 * conversion_.distance_mm.slope(c_h)) * 3.3 / 4096.0;
    sensitivity.push(std::move(row));
  }
  out["sensitivity"] = std::move(sensitivity);
  out["clamped_samples"] = static_cast<std::uint64_t>(clamps_.load(std::memory_order_relaxed));
}

namespace {

constexpr ParamDoc kParams[] = {
    {"channel", "text", "hall", "name of the Hall-voltage element in the signals input [V]"},
    {"output_name", "text", "gap", "name of the output element [m]"},
    {"coil_polynomial_v", "list<number>", "[1.299e-6, 9.05e-5, 2.544]",
     "eq. 15: quiescent + coil-induced Hall voltage vs coil voltage, descending powers [V/V^n]"},
    {"distance_polynomial_mm", "list<number>", "[-563.9, 1351.6, -1284.2, 633.1, -183.9, 46.9]",
     "eq. 16: M_H, distance [mm] vs C_H [V], descending powers"},
    {"compensated_range_v", "list<number>[2]", "[0, 0.8]", "C_H clamp [V]; M_H must decrease strictly on it"},
};

constexpr PortSpec kPorts[] = {
    {"signals", PortDirection::in, "the Hall voltage [V], element `channel` (e.g. io.sim signals)"},
    {"coil_voltage", PortDirection::in, "optional: coil_voltage [V] held at the sample (e.g. io.sim truth)"},
    {"gap", PortDirection::out, "d_hall [m] (eq. 14)"},
    {"compensated", PortDirection::out, "C_H [V] (eq. 15), before the clamp"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::HallDirect, "estimator.hall_direct", lode::PluginKind::estimator, "0.1.0",
            "Direct Hall distance of Sensors 2016 (eq. 14-16, coil-compensated static characteristic), the baseline",
            lode::plugins::kParams, lode::plugins::kPorts)
