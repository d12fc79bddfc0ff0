// Helpers for the plant plugins' tests.
#pragma once

#include <array>
#include <string>

#include "lode/sdk/port.hpp"

namespace lode::plugins::plants::testing {

/// The plant's full state (PlantModel::state()) as an array of its kStateSize.
template <typename Plant>
std::array<double, Plant::kStateSize> state_of(const Plant& plant) {
  std::array<double, Plant::kStateSize> x{};
  plant.state(x.data());
  return x;
}

/// "fx [N], fy [N], tz [N*m]": names and units in order, to compare a whole port at once.
inline std::string element_list(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out;
}

}  // namespace lode::plugins::plants::testing
