// Models as describe() JSON, beside the SDK's matrices and vectors (lode/sdk/json_eigen.hpp),
// the form every estimator reports its gains, covariances and models in (off the RT thread).
#pragma once

#include <Eigen/Core>
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

}  // namespace lode::plugins::estimator
