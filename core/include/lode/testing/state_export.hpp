// Helpers for plugin tests of the estimator-state API (Block::state_layout / export_state,
// used by hot swap): take a block's exported state as vectors, and check an exported
// covariance is a usable one.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <vector>

#include "lode/sdk/block.hpp"

namespace lode::testing {

struct ExportedState {
  std::vector<double> values;
  std::vector<double> covariance;  ///< row-major n x n; NaN when the layout has none
};

/// The block's exported state. Elements the block does not write stay NaN, so a test sees them.
inline ExportedState export_state_of(Block& block) {
  const StateLayout layout = block.state_layout();
  ExportedState e;
  e.values.assign(layout.size(), std::nan(""));
  e.covariance.assign(layout.size() * layout.size(), std::nan(""));
  block.export_state(e.values.data(), layout.covariance ? e.covariance.data() : nullptr);
  return e;
}

/// Finite, exactly symmetric and positive definite (Cholesky succeeds): what import_state and
/// the health monitor's covariance check rely on.
inline bool covariance_usable(const std::vector<double>& cov, std::size_t n) {
  const auto size = static_cast<Eigen::Index>(n);
  if (cov.size() != n * n) return false;
  Eigen::MatrixXd p(size, size);
  for (Eigen::Index i = 0; i < size; ++i)
    for (Eigen::Index j = 0; j < size; ++j) p(i, j) = cov[static_cast<std::size_t>(i * size + j)];
  if (!p.allFinite() || p != p.transpose()) return false;
  return Eigen::LLT<Eigen::MatrixXd>(p).info() == Eigen::Success;
}

}  // namespace lode::testing
