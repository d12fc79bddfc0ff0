// lode::math discretisation: expm, zoh and van_loan against closed forms and against an
// independent reference (long-double Taylor series, RK4 integration, Simpson quadrature) on a
// random 6x6 system; tustin (with prewarp) and matched pole-zero against hand-derived
// coefficients and the reference table of the Silva-Rivas & Kim (2013) notch (eqs. 31-33 by
// prewarped Tustin, worked out independently).
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "lode/sdk/math/discretize.hpp"

namespace {

using lode::math::Matrix;
using lode::math::TransferFunction;
using lode::math::Vector;
using lode::math::Zpk;
using Complex = std::complex<double>;
using LongMatrix = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;

constexpr double kPi = std::numbers::pi;

double relative_error(const Matrix& actual, const Matrix& expected) {
  return (actual - expected).norm() / expected.norm();
}

Matrix random_matrix(Eigen::Index rows, Eigen::Index cols, unsigned seed, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, scale);
  Matrix M(rows, cols);
  for (Eigen::Index i = 0; i < rows; ++i) {
    for (Eigen::Index j = 0; j < cols; ++j) M(i, j) = normal(rng);
  }
  return M;
}

/// Independent reference: e^M by a 40-term Taylor series in long double after scaling the norm
/// below 1/2, then squaring.
Matrix expm_reference(const Matrix& M) {
  const LongMatrix A = M.cast<long double>();
  const long double norm = A.cwiseAbs().colwise().sum().maxCoeff();
  int squarings = 0;
  while (norm / std::ldexp(1.0L, squarings) > 0.5L) ++squarings;
  const LongMatrix scaled = A / std::ldexp(1.0L, squarings);
  LongMatrix term = LongMatrix::Identity(A.rows(), A.cols());
  LongMatrix sum = term;
  for (int k = 1; k <= 40; ++k) {
    term = term * scaled / static_cast<long double>(k);
    sum += term;
  }
  for (int i = 0; i < squarings; ++i) sum = sum * sum;
  return sum.cast<double>();
}

/// x' = A x + B u with u = e_j held for T: RK4 with `steps` steps from x = 0 gives column j of Bd.
Matrix zoh_input_by_rk4(const Matrix& A, const Matrix& B, double T, int steps) {
  Matrix Bd(A.rows(), B.cols());
  const double h = T / steps;
  for (Eigen::Index j = 0; j < B.cols(); ++j) {
    Vector x = Vector::Zero(A.rows());
    const Vector u = B.col(j);
    auto f = [&](const Vector& state) -> Vector { return A * state + u; };
    for (int k = 0; k < steps; ++k) {
      const Vector k1 = f(x);
      const Vector k2 = f(x + 0.5 * h * k1);
      const Vector k3 = f(x + 0.5 * h * k2);
      const Vector k4 = f(x + h * k3);
      x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    Bd.col(j) = x;
  }
  return Bd;
}

std::vector<double> tf_coefficients_error(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> out;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) out.push_back(std::abs(a[i] - b[i]));
  return out;
}

// --- expm ---------------------------------------------------------------------------------

TEST(MathExpm, ClosedForms) {
  EXPECT_LT((lode::math::expm(Matrix::Zero(3, 3)) - Matrix::Identity(3, 3)).norm(), 1e-15);

  // Nilpotent: e^{[[0, T], [0, 0]]} = [[1, T], [0, 1]].
  Matrix N(2, 2);
  N << 0.0, 0.25, 0.0, 0.0;
  Matrix expected(2, 2);
  expected << 1.0, 0.25, 0.0, 1.0;
  EXPECT_LT((lode::math::expm(N) - expected).norm(), 1e-15);

  // Rotation generator at every Padé degree and with squaring: e^{[[0, -w], [w, 0]]}.
  for (double w : {1e-3, 0.1, 0.5, 1.5, 4.0, 37.0, 600.0}) {
    Matrix R(2, 2);
    R << 0.0, -w, w, 0.0;
    Matrix rotation(2, 2);
    rotation << std::cos(w), -std::sin(w), std::sin(w), std::cos(w);
    EXPECT_LT((lode::math::expm(R) - rotation).norm(), 1e-14 * std::max(1.0, w)) << "w = " << w;
  }

  // Stiff upper-triangular: e^{[[a, 1], [0, b]]} = [[e^a, (e^a - e^b)/(a - b)], [0, e^b]].
  const double a = -50.0;
  const double b = -80.0;
  Matrix S(2, 2);
  S << a, 1.0, 0.0, b;
  Matrix stiff(2, 2);
  stiff << std::exp(a), (std::exp(a) - std::exp(b)) / (a - b), 0.0, std::exp(b);
  EXPECT_LT(relative_error(lode::math::expm(S), stiff), 1e-12);
}

TEST(MathExpm, RandomSixBySixAgainstLongDoubleSeries) {
  for (unsigned seed : {1u, 2u, 3u}) {
    for (double scale : {0.01, 0.3, 2.0, 10.0}) {
      const Matrix M = random_matrix(6, 6, seed, scale);
      const double error = relative_error(lode::math::expm(M), expm_reference(M));
      EXPECT_LT(error, 1e-12) << "seed " << seed << ", scale " << scale;
    }
  }
}

// --- zoh ----------------------------------------------------------------------------------

TEST(MathZoh, DoubleIntegratorAndFirstOrderLag) {
  const double T = 1.25e-3;
  Matrix A(2, 2);
  A << 0.0, 1.0, 0.0, 0.0;
  Matrix B(2, 1);
  B << 0.0, 1.0 / 1.52;  // 1 N on 1.52 kg
  const auto d = lode::math::zoh(A, B, T);
  Matrix Ad(2, 2);
  Ad << 1.0, T, 0.0, 1.0;
  Matrix Bd(2, 1);
  Bd << T * T / 2.0 / 1.52, T / 1.52;
  EXPECT_LT((d.Ad - Ad).norm(), 1e-15);
  EXPECT_LT(relative_error(d.Bd, Bd), 1e-14);

  // x' = -a x + b u: Ad = e^{-aT}, Bd = b (1 - e^{-aT}) / a.
  const double a = 300.0;
  const double b = 2.0;
  const auto lag = lode::math::zoh(Matrix::Constant(1, 1, -a), Matrix::Constant(1, 1, b), T);
  EXPECT_NEAR(lag.Ad(0, 0), std::exp(-a * T), 1e-15);
  EXPECT_NEAR(lag.Bd(0, 0) / (b * (1.0 - std::exp(-a * T)) / a), 1.0, 1e-13);
}

TEST(MathZoh, RandomSixBySixAgainstRk4) {
  const Matrix A = random_matrix(6, 6, 11, 3.0);
  const Matrix B = random_matrix(6, 2, 12);
  const double T = 0.05;
  const auto d = lode::math::zoh(A, B, T);
  EXPECT_LT(relative_error(d.Ad, expm_reference(A * T)), 1e-13);
  const double error = relative_error(d.Bd, zoh_input_by_rk4(A, B, T, 4000));
  std::printf("zoh 6x6: |Bd - Bd_rk4| / |Bd_rk4| = %.2e\n", error);
  EXPECT_LT(error, 1e-11);
}

// --- van_loan -----------------------------------------------------------------------------

TEST(MathVanLoan, ClosedForms) {
  const double T = 1.25e-3;
  const double q = 100.0;
  // Constant acceleration driven by white jerk of intensity q (state: position, velocity,
  // acceleration): Qd = q [[T^5/20, T^4/8, T^3/6], [T^4/8, T^3/3, T^2/2], [T^3/6, T^2/2, T]].
  Matrix A = Matrix::Zero(3, 3);
  A(0, 1) = 1.0;
  A(1, 2) = 1.0;
  Matrix G(3, 1);
  G << 0.0, 0.0, 1.0;
  const auto d = lode::math::van_loan(A, G, Matrix::Constant(1, 1, q), T);
  Matrix Qd(3, 3);
  Qd << std::pow(T, 5) / 20, std::pow(T, 4) / 8, std::pow(T, 3) / 6,  //
      std::pow(T, 4) / 8, std::pow(T, 3) / 3, T * T / 2,              //
      std::pow(T, 3) / 6, T * T / 2, T;
  Qd *= q;
  Matrix Ad(3, 3);
  Ad << 1, T, T * T / 2, 0, 1, T, 0, 0, 1;
  EXPECT_LT((d.Ad - Ad).norm(), 1e-15);
  for (Eigen::Index i = 0; i < 3; ++i) {
    for (Eigen::Index j = 0; j < 3; ++j) {
      EXPECT_NEAR(d.Qd(i, j) / Qd(i, j), 1.0, 1e-9) << i << "," << j;
    }
  }

  // First-order lag x' = -a x + w: Qd = q (1 - e^{-2aT}) / (2a).
  const double a = 40.0;
  const auto lag = lode::math::van_loan(Matrix::Constant(1, 1, -a), Matrix::Identity(1, 1),
                                        Matrix::Constant(1, 1, q), 0.01);
  EXPECT_NEAR(lag.Qd(0, 0) / (q * (1.0 - std::exp(-2.0 * a * 0.01)) / (2.0 * a)), 1.0, 1e-13);
}

TEST(MathVanLoan, RandomSixBySixAgainstQuadrature) {
  const Matrix A = random_matrix(6, 6, 21, 2.0);
  const Matrix G = random_matrix(6, 3, 22);
  Matrix Qc = random_matrix(3, 3, 23);
  Qc = Qc * Qc.transpose() + Matrix::Identity(3, 3);
  const double T = 0.1;
  const auto d = lode::math::van_loan(A, G, Qc, T);

  // Composite Simpson over [0, T] of e^{As} G Qc G' e^{A's}.
  const int intervals = 400;
  const double h = T / intervals;
  const Matrix W = G * Qc * G.transpose();
  Matrix integral = Matrix::Zero(6, 6);
  for (int k = 0; k <= intervals; ++k) {
    const Matrix E = expm_reference(A * (k * h));
    const double weight = (k == 0 || k == intervals) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
    integral += weight * E * W * E.transpose();
  }
  integral *= h / 3.0;
  const double error = relative_error(d.Qd, integral);
  std::printf("van_loan 6x6: |Qd - Qd_simpson| / |Qd_simpson| = %.2e\n", error);
  EXPECT_LT(error, 1e-10);
  EXPECT_LT((d.Qd - d.Qd.transpose()).norm(), 1e-15 * d.Qd.norm());
  EXPECT_LT(relative_error(d.Ad, expm_reference(A * T)), 1e-13);
}

// --- polynomials --------------------------------------------------------------------------

TEST(MathPolynomials, FromRootsAndBack) {
  const std::vector<Complex> roots{{-1.0, 2.0}, {-1.0, -2.0}, {3.0, 0.0}};
  const std::vector<double> p = lode::math::poly_from_roots(roots);  // (s^2 + 2s + 5)(s - 3)
  const std::vector<double> expected{1.0, -1.0, -1.0, -15.0};
  ASSERT_EQ(p.size(), expected.size());
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_NEAR(p[i], expected[i], 1e-14);
  const auto back = lode::math::poly_roots(p);
  ASSERT_EQ(back.size(), 3u);
  EXPECT_NEAR(std::abs(back[0] - Complex(3.0, 0.0)), 0.0, 1e-13);
  EXPECT_NEAR(std::abs(back[1] - Complex(-1.0, 2.0)), 0.0, 1e-13);
  EXPECT_NEAR(std::abs(back[2] - Complex(-1.0, -2.0)), 0.0, 1e-13);
  EXPECT_TRUE(lode::math::poly_roots({0.0, 2.0}).empty());  // a constant has no roots
}

// --- tustin -------------------------------------------------------------------------------

TEST(MathTustin, FirstOrderLowPassClosedForm) {
  // a/(s + a) -> (aT/(2 + aT)) (z + 1) / (z + (aT - 2)/(aT + 2)).
  const double a = 2.0 * kPi * 30.0;
  const double T = 1.0 / 800.0;
  const TransferFunction d = lode::math::tustin(TransferFunction{{a}, {1.0, a}}, T);
  ASSERT_EQ(d.num.size(), 2u);
  ASSERT_EQ(d.den.size(), 2u);
  const double g = a * T / (2.0 + a * T);
  EXPECT_NEAR(d.num[0], g, 1e-15);
  EXPECT_NEAR(d.num[1], g, 1e-15);
  EXPECT_DOUBLE_EQ(d.den[0], 1.0);
  EXPECT_NEAR(d.den[1], (a * T - 2.0) / (a * T + 2.0), 1e-15);
  // The same map root by root.
  const TransferFunction z = lode::math::tustin(Zpk{{}, {Complex(-a, 0.0)}, a}, T);
  for (double e : tf_coefficients_error(z.num, d.num)) EXPECT_LT(e, 1e-15);
  for (double e : tf_coefficients_error(z.den, d.den)) EXPECT_LT(e, 1e-15);
}

TEST(MathTustin, PrewarpIsExactAtItsFrequency) {
  // A resonant second-order low-pass: plain Tustin misplaces the peak, prewarped matches it.
  const double wn = 2.0 * kPi * 150.0;
  const TransferFunction h{{wn * wn}, {1.0, 2.0 * 0.2 * wn, wn * wn}};
  const double T = 1.0 / 800.0;
  const TransferFunction warped = lode::math::tustin(h, T, wn);
  const TransferFunction plain = lode::math::tustin(h, T);
  const Complex exact = lode::math::continuous_response(h, wn);
  EXPECT_LT(std::abs(lode::math::discrete_response(warped, wn, T) - exact), 1e-12 * std::abs(exact));
  EXPECT_GT(std::abs(lode::math::discrete_response(plain, wn, T) - exact), 0.1 * std::abs(exact));
  // Both keep the DC gain.
  EXPECT_NEAR(std::abs(lode::math::discrete_response(warped, 0.0, T)), 1.0, 1e-13);
}

TEST(MathTustin, Seed003NotchReferenceTable) {
  // Silva-Rivas & Kim (2013) eqs. 31-33: H(s) = (k s^2 + w0^2)/(s^2 + 2 zeta w0 s + w0^2),
  // w0 = 2 pi 50 sqrt(k), zeta = 0.5, k = 0.1, Tustin prewarped at 50 Hz; coefficients worked
  // out independently to 6 decimals.
  struct Row {
    double fs;
    double b0, b1, a1, a2;
  };
  const Row table[] = {{800.0, 0.097442, -0.180049, -1.867246, 0.882081},
                       {834.2, 0.097408, -0.181163, -1.873066, 0.886719},
                       {1000.0, 0.097387, -0.185240, -1.895301, 0.904834},
                       {2000.0, 0.098117, -0.193817, -1.949047, 0.951463}};
  const double k = 0.1;
  const double zeta = 0.5;
  const double w_notch = 2.0 * kPi * 50.0;
  const double w0 = w_notch * std::sqrt(k);
  for (const Row& row : table) {
    const double T = 1.0 / row.fs;
    const TransferFunction d =
        lode::math::tustin(TransferFunction{{k, 0.0, w0 * w0}, {1.0, 2.0 * zeta * w0, w0 * w0}}, T, w_notch);
    ASSERT_EQ(d.num.size(), 3u);
    EXPECT_NEAR(d.num[0], row.b0, 6e-7) << row.fs;
    EXPECT_NEAR(d.num[1], row.b1, 6e-7) << row.fs;
    EXPECT_NEAR(d.num[2], row.b0, 6e-7) << row.fs;
    EXPECT_NEAR(d.den[1], row.a1, 6e-7) << row.fs;
    EXPECT_NEAR(d.den[2], row.a2, 6e-7) << row.fs;
    EXPECT_LT(std::abs(lode::math::discrete_response(d, w_notch, T)), 1e-12) << "null at 50 Hz";
    EXPECT_NEAR(std::abs(lode::math::discrete_response(d, 0.0, T)), 1.0, 1e-12);
    EXPECT_NEAR(20.0 * std::log10(std::abs(lode::math::discrete_response(d, kPi / T, T))), -20.0, 1e-9);
  }
}

// --- matched pole-zero --------------------------------------------------------------------

TEST(MathMatchedPoleZero, FirstOrderLagAndResonance) {
  const double T = 1e-3;
  // a/(s + a): pole e^{-aT}, the zero at infinity -> z = -1, DC gain 1.
  const double a = 200.0;
  const TransferFunction lag = lode::math::matched_pole_zero(Zpk{{}, {Complex(-a, 0.0)}, a}, T);
  const double p = std::exp(-a * T);
  ASSERT_EQ(lag.den.size(), 2u);
  EXPECT_NEAR(lag.den[1], -p, 1e-15);
  EXPECT_NEAR(lag.num[0], (1.0 - p) / 2.0, 1e-15);
  EXPECT_NEAR(lag.num[1], (1.0 - p) / 2.0, 1e-15);

  // Complex pair: den = z^2 - 2 e^{-zeta wn T} cos(wd T) z + e^{-2 zeta wn T}; DC gain kept.
  const double wn = 400.0;
  const double zeta = 0.3;
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  const Zpk resonance{{}, {Complex(-zeta * wn, wd), Complex(-zeta * wn, -wd)}, wn * wn};
  const TransferFunction d = lode::math::matched_pole_zero(resonance, T);
  ASSERT_EQ(d.den.size(), 3u);
  EXPECT_NEAR(d.den[1], -2.0 * std::exp(-zeta * wn * T) * std::cos(wd * T), 1e-15);
  EXPECT_NEAR(d.den[2], std::exp(-2.0 * zeta * wn * T), 1e-15);
  EXPECT_NEAR(std::abs(lode::math::discrete_response(d, 0.0, T)), 1.0, 1e-13);
  // Two zeros at infinity -> (z + 1)^2 in the numerator.
  EXPECT_NEAR(d.num[1] / d.num[0], 2.0, 1e-13);
  EXPECT_NEAR(d.num[2] / d.num[0], 1.0, 1e-13);
}

TEST(MathMatchedPoleZero, IntegratorMatchesTheVelocityConstant) {
  // D(s) = K (s + 50)/(s (s + 2000)): lim s D(s) = K 50/2000 must equal lim (z-1)/T D(z).
  const double T = 1.25e-3;
  const double K = 1e4;
  const TransferFunction d =
      lode::math::matched_pole_zero(Zpk{{Complex(-50.0, 0.0)}, {Complex(0.0, 0.0), Complex(-2000.0, 0.0)}, K}, T);
  ASSERT_EQ(d.den.size(), 3u);
  auto at = [&](Complex z) {
    Complex n = 0.0;
    Complex m = 0.0;
    for (double c : d.num) n = n * z + c;
    for (double c : d.den) m = m * z + c;
    return n / m;
  };
  const Complex z_near_one(1.0 + 1e-7, 0.0);
  const double velocity_constant = ((z_near_one - 1.0) / T * at(z_near_one)).real();
  EXPECT_NEAR(velocity_constant / (K * 50.0 / 2000.0), 1.0, 1e-5);
  EXPECT_NEAR(d.den[1], -(1.0 + std::exp(-2000.0 * T)), 1e-15);
}

}  // namespace
