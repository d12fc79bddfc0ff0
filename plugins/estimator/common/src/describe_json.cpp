#include "estimator/describe_json.hpp"

#include <cmath>
#include <numbers>

namespace lode::plugins::estimator {

Json error_pole_json(std::complex<double> z, double period_s, PoleRate rate) {
  Json p = Json::object();
  p["re"] = z.real();
  p["im"] = z.imag();
  p["abs"] = std::abs(z);
  if (rate == PoleRate::hz) {
    p["continuous_hz"] = std::abs(std::log(z)) / (2.0 * std::numbers::pi * period_s);
  } else {
    p["continuous_rad_s"] = std::abs(std::log(z)) / period_s;
  }
  return p;
}

}  // namespace lode::plugins::estimator
