#include "estimator/element_names.hpp"

namespace lode::plugins::estimator {

std::string element_list(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out.empty() ? "(none)" : out;
}

Elements rate_elements(const Elements& positions) {
  Elements out;
  for (const Element& e : positions) out.push_back({e.name + "_dot", e.unit + "/s"});
  return out;
}

Elements acceleration_elements(const Elements& positions) {
  Elements out;
  for (const Element& e : positions) out.push_back({e.name + "_ddot", e.unit + "/s^2"});
  return out;
}

}  // namespace lode::plugins::estimator
