// Eigen matrices and vectors as describe() JSON: the form gains, covariances and model
// matrices are reported in by every plugin that has them (off the RT thread: it allocates).
#pragma once

#include <Eigen/Core>

#include <vector>

#include "lode/sdk/json.hpp"

namespace lode {

/// Rows of numbers, row-major: [[m00, m01, ...], [m10, ...], ...].
template <typename Derived>
Json matrix_json(const Eigen::MatrixBase<Derived>& m) {
  Json rows = Json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    std::vector<double> row;
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push(Json(row));
  }
  return rows;
}

/// The elements of a vector, in order.
template <typename Derived>
std::vector<double> vector_values(const Eigen::MatrixBase<Derived>& v) {
  std::vector<double> out;
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

}  // namespace lode
