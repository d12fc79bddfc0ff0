// Models as describe() JSON, beside the SDK's matrices and vectors (lode/sdk/json_eigen.hpp),
// the form every estimator reports its gains, covariances and models in (off the RT thread).
#pragma once

#include <Eigen/Core>
#include <array>
#include <complex>
#include <cstddef>
#include <vector>

#include "lode/sdk/json.hpp"
#include "lode/sdk/json_eigen.hpp"

namespace lode::plugins::estimator {

using lode::matrix_json;    // lode/sdk/json_eigen.hpp
using lode::vector_values;

/// What a model (measurement, process or plant model) says of itself in its describe().
template <typename Model>
Json description_of(const Model& model) {
  Json out = Json::object();
  model.describe(out);
  return out;
}

/// The continuous-time rate a discrete pole z stands for, |ln z| / T: in rad/s or in Hz.
enum class PoleRate { rad_s, hz };

/// One pole z of a filter's discrete error dynamics: {re, im, abs, continuous_rad_s} (or
/// continuous_hz, with PoleRate::hz).
Json error_pole_json(std::complex<double> z, double period_s, PoleRate rate = PoleRate::rad_s);

/// Poles held as (re, im) pairs (estimator/position_gain.hpp error_poles()), each as above.
template <std::size_t N>
Json error_poles_json(const std::array<std::array<double, 2>, N>& poles, double period_s,
                      PoleRate rate = PoleRate::rad_s) {
  Json out = Json::array();
  for (const auto& z : poles) out.push(error_pole_json(std::complex<double>(z[0], z[1]), period_s, rate));
  return out;
}

}  // namespace lode::plugins::estimator
