// lode::math statistics against closed forms and published table values: the chi-square
// quantile with 2 degrees of freedom is -2 ln(1 - p) exactly; the others are the values of
// standard tables (Abramowitz & Stegun 1964, table 26.8), to their printed digits.
#include <gtest/gtest.h>

#include <cmath>

#include "lode/sdk/math/statistics.hpp"

namespace {

using lode::math::chi_square_quantile;
using lode::math::normal_quantile;
using lode::math::regularized_gamma_p;

TEST(Statistics, ChiSquareTwoDegreesIsClosedForm) {
  for (const double p : {1e-6, 0.025, 0.5, 0.975, 0.999999})
    EXPECT_NEAR(chi_square_quantile(p, 2.0), -2.0 * std::log1p(-p), 1e-9 * (1.0 - 2.0 * std::log1p(-p))) << p;
}

TEST(Statistics, ChiSquareAgainstTables) {
  EXPECT_NEAR(chi_square_quantile(0.975, 1), 5.02389, 1e-5);
  EXPECT_NEAR(chi_square_quantile(0.025, 1), 0.000982069, 1e-9);
  EXPECT_NEAR(chi_square_quantile(0.025, 3), 0.215795, 1e-6);
  EXPECT_NEAR(chi_square_quantile(0.975, 3), 9.34840, 1e-5);
  EXPECT_NEAR(chi_square_quantile(0.99, 10), 23.2093, 1e-4);
  EXPECT_NEAR(chi_square_quantile(0.001, 30), 11.5880, 1e-4);
}

TEST(Statistics, ChiSquareOutsideItsDomainIsNaN) {
  EXPECT_TRUE(std::isnan(chi_square_quantile(0.0, 3)));
  EXPECT_TRUE(std::isnan(chi_square_quantile(1.0, 3)));
  EXPECT_TRUE(std::isnan(chi_square_quantile(0.5, 0)));
}

TEST(Statistics, NormalQuantileAndGammaAgreeWithTables) {
  EXPECT_NEAR(normal_quantile(0.975), 1.959964, 1e-6);
  EXPECT_NEAR(normal_quantile(0.5), 0.0, 1e-12);
  EXPECT_NEAR(normal_quantile(1e-6), -4.753424, 1e-6);
  // P(1, x) = 1 - e^-x; P(1/2, x) = erf(sqrt(x)).
  EXPECT_NEAR(regularized_gamma_p(1.0, 2.0), 1.0 - std::exp(-2.0), 1e-14);
  EXPECT_NEAR(regularized_gamma_p(0.5, 0.3), std::erf(std::sqrt(0.3)), 1e-14);
  EXPECT_NEAR(regularized_gamma_p(0.5, 30.0), std::erf(std::sqrt(30.0)), 1e-14);
}

}  // namespace
