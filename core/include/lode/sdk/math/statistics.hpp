// Distribution functions the estimator statistics need (the chi-square interval of the
// normalised innovation squared).
#pragma once

namespace lode::math {

/// Regularized lower incomplete gamma function P(a, x), a > 0, x >= 0.
double regularized_gamma_p(double a, double x);

/// Standard normal quantile: the z with Phi(z) = p, 0 < p < 1.
double normal_quantile(double p);

/// Chi-square quantile with k degrees of freedom at probability p, exact to ~1e-12 (the
/// root of P(k/2, x/2) = p); NaN outside 0 < p < 1, k > 0.
double chi_square_quantile(double p, double k);

}  // namespace lode::math
