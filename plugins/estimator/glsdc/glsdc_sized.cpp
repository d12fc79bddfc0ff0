// estimator.glsdc's sized path: 3dof over kSizedChannels channels on storage sized at compile
// time. It performs the generic path's floating-point operations in the same order (so the
// same bits), and skips the work the generic path repeats:
//   - the trial point z + dz is evaluated with jacobian() instead of evaluate(): when the step
//     is accepted, z + dz is the next linearisation point and is already linearised (the
//     generic path evaluates it again at the end of the tick);
//   - R = (H'WH)^-1 depends on the linearisation only (not on the measurement): it is kept
//     with it, so the next tick's first step (warm-started at the same z) reuses it instead of
//     factoring the same H'WH again.
// With iterations: 1 a tick is one jacobian() and one factorisation instead of two jacobian(),
// one evaluate() and two factorisations.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "estimator/weighted_least_squares.hpp"
#include "glsdc.hpp"

namespace lode::plugins {

namespace {

double sized_cost(const Glsdc::SizedVector& y, const Glsdc::SizedVector& f, const Glsdc::SizedVector& w) noexcept {
  return estimator::weighted_cost(y, f, w, static_cast<std::size_t>(Glsdc::kSizedChannels));
}

/// Largest absolute column sum.
double l1_norm(const Glsdc::Covariance& m) noexcept {
  double norm = 0.0;
  for (int j = 0; j < m.cols(); ++j) norm = std::max(norm, m.col(j).cwiseAbs().sum());
  return norm;
}

/// True when N is clearly better conditioned than Glsdc::kMinRcond, judged from the solved
/// R = N^-1 (LDLT's solve operator) without the cost of Eigen's rcond() estimate (a third of
/// the factorisation's cost). That estimate is 1 / (|N|_1 x est) with est = |R x|_1 for a
/// unit x, so est <= |R|_1 and rcond() >= 1 / (|N|_1 |R|_1): when this bound exceeds the
/// threshold a hundredfold (room for rounding), rcond() passes the threshold too, and the
/// decision is the generic path's. Otherwise (or on NaN) the caller asks rcond() itself.
bool well_conditioned(const Glsdc::Covariance& normal, const Glsdc::Covariance& r) noexcept {
  constexpr double kMargin = 100.0;
  const double reciprocal_condition = 1.0 / (l1_norm(normal) * l1_norm(r));
  return reciprocal_condition >= kMargin * Glsdc::kMinRcond;
}

}  // namespace

void Glsdc::linearise_sized(const State& z) noexcept {
  if (linearisation_valid_ && z == linearised_at_) return;
  model_->jacobian(z.data(), sized_work_.predicted.data(), sized_work_.jacobian.data());
  linearised_at_ = z;
  linearisation_valid_ = true;
  sized_work_.factor_valid = false;
}

bool Glsdc::solve_sized(Covariance& r, State& dz) noexcept {
  Sized& s = sized_work_;
  // g = H'W(y - f) (eq. 4.27), each element summed over the channels in the generic order.
  State gradient = State::Zero();
  for (int i = 0; i < kSizedChannels; ++i) {
    const double w = s.weight(i);
    const double residual = s.measured(i) - s.predicted(i);
    for (int a = 0; a < kStates; ++a) gradient(a) += s.jacobian(i, a) * w * residual;
  }
  if (!s.factor_valid) {
    // N = H'WH (eq. 4.28), every element as the generic path sums it (not mirrored: the
    // products (H_ia w) H_ib and (H_ib w) H_ia may differ in the last bit).
    Covariance normal = Covariance::Zero();
    for (int i = 0; i < kSizedChannels; ++i) {
      const double w = s.weight(i);
      for (int a = 0; a < kStates; ++a) {
        for (int b = 0; b < kStates; ++b) normal(a, b) += s.jacobian(i, a) * w * s.jacobian(i, b);
      }
    }
    const Eigen::LDLT<Covariance> ldlt(normal);
    s.factor_ok = ldlt.info() == Eigen::Success && ldlt.isPositive();
    if (s.factor_ok) {
      // Column by column: the matrix right-hand side runs Eigen's general blocked triangular
      // solver, several times the cost for 3 x 3 (same results, checked against the generic path).
      for (int j = 0; j < kStates; ++j) s.factor_r.col(j) = ldlt.solve(State::Unit(j));
      s.factor_ok = well_conditioned(normal, s.factor_r) || ldlt.rcond() >= kMinRcond;
    }
    s.factor_valid = true;
  }
  if (!s.factor_ok) return false;
  r = s.factor_r;
  dz = r * gradient;  // Gauss-Newton step R H'W dy
  return r.allFinite() && dz.allFinite();
}

bool Glsdc::iterate_sized() noexcept {
  Sized& s = sized_work_;
  for (std::int64_t it = 0; it < iterations_; ++it) {
    linearise_sized(z_);
    const double cost_before = sized_cost(s.measured, s.predicted, s.weight);
    Covariance r;
    State dz;
    if (!solve_sized(r, dz)) return true;  // singular: hold the estimate (skip the update)
    const State z_full = z_ + dz;
    model_->jacobian(z_full.data(), s.trial.data(), s.trial_jacobian.data());
    const double cost_after = sized_cost(s.measured, s.trial, s.weight);
    if (cost_after > cost_before) {
      // Thesis Appendix B/C: z <- z + dz - (1 - backoff) dz, no re-check.
      z_ += backoff_ * dz;
      ++backoffs_;
    } else {
      z_ = z_full;
      // z + dz is linearised already: it becomes the current linearisation.
      s.predicted = s.trial;
      s.jacobian = s.trial_jacobian;
      linearised_at_ = z_full;
      linearisation_valid_ = true;
      s.factor_valid = false;
    }
  }
  return false;
}

bool Glsdc::finish_sized(Covariance& r) noexcept {
  linearise_sized(z_);
  cost_value_ = sized_cost(sized_work_.measured, sized_work_.predicted, sized_work_.weight);
  if (!std::isfinite(cost_value_)) return false;
  State dz;
  return solve_sized(r, dz);
}

}  // namespace lode::plugins
