// The covariance an estimator takes over at a hot swap (import_state(), RT thread): whatever
// the incumbent handed over, the filter must go on with a symmetric positive definite P.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>

namespace lode::plugins::estimator {

/// 0.5 (P + P') if that is finite and positive definite (Cholesky succeeds); else the diagonal
/// of P alone, with `fallback_variance(i)` (the block's own initial variance) wherever P(i, i)
/// is not finite and > 0. No allocation for fixed-size or fixed-capacity matrices.
template <typename Matrix, typename Fallback>
Matrix usable_covariance(const Matrix& p, const Fallback& fallback_variance) noexcept {
  Matrix sym = 0.5 * (p + p.transpose());
  if (sym.allFinite()) {
    const Eigen::LLT<Matrix> llt(sym);
    if (llt.info() == Eigen::Success) return sym;
  }
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    for (Eigen::Index j = 0; j < p.cols(); ++j) {
      const double v = p(i, i);
      sym(i, j) = i != j ? 0.0 : (std::isfinite(v) && v > 0.0 ? v : fallback_variance(i));
    }
  }
  return sym;
}

}  // namespace lode::plugins::estimator
