// Continuous-to-discrete conversions (configure time): matrix exponential, zero-order hold,
// Van Loan's process-noise integral, Tustin with prewarp, matched pole-zero.
#include "lode/sdk/math/discretize.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>

namespace lode::math {

namespace {

using Complex = std::complex<double>;
using ComplexPolynomial = std::vector<Complex>;

/// Roots closer than this to s = 0 [rad/s] are treated as lying at the origin (integrators,
/// differentiators): they map to z = 1 exactly and take part in the gain matching.
constexpr double kOriginTolerance = 1e-12;

/// Padé [m/m] numerator coefficients b_0..b_m of Higham (2005), Table 2.3 / eq. 2.4.
constexpr std::array<double, 4> kPade3 = {120.0, 60.0, 12.0, 1.0};
constexpr std::array<double, 6> kPade5 = {30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0};
constexpr std::array<double, 8> kPade7 = {17297280.0, 8648640.0, 1995840.0, 277200.0,
                                          25200.0,    1512.0,    56.0,      1.0};
constexpr std::array<double, 10> kPade9 = {17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0,
                                           2162160.0,     110880.0,     3960.0,       90.0,        1.0};
constexpr std::array<double, 14> kPade13 = {64764752532480000.0,
                                            32382376266240000.0,
                                            7771770303897600.0,
                                            1187353796428800.0,
                                            129060195264000.0,
                                            10559470521600.0,
                                            670442572800.0,
                                            33522128640.0,
                                            1323241920.0,
                                            40840800.0,
                                            960960.0,
                                            16380.0,
                                            182.0,
                                            1.0};
/// theta_m: the largest 1-norm for which the [m/m] approximant is accurate to unit roundoff
/// (Higham 2005, Table 2.3).
constexpr double kTheta3 = 1.495585217958292e-2;
constexpr double kTheta5 = 2.539398330063230e-1;
constexpr double kTheta7 = 9.504178996162932e-1;
constexpr double kTheta9 = 2.097847961257068e0;
constexpr double kTheta13 = 5.371920351148152e0;

/// r_m(A) = (V - U)^-1 (V + U) with U the odd and V the even part of the Padé numerator,
/// for m in {3, 5, 7, 9} (Higham 2005, Algorithm 2.3 lines 2-6).
template <std::size_t Size>
Matrix pade_low_order(const Matrix& A, const std::array<double, Size>& b) {
  const Eigen::Index n = A.rows();
  const Matrix identity = Matrix::Identity(n, n);
  const Matrix A2 = A * A;
  Matrix power = identity;  // A^{2j}
  Matrix odd = Matrix::Zero(n, n);
  Matrix even = Matrix::Zero(n, n);
  for (std::size_t j = 0; 2 * j + 1 < Size; ++j) {
    even += b[2 * j] * power;
    odd += b[2 * j + 1] * power;
    power = power * A2;
  }
  const Matrix U = A * odd;
  return (even - U).partialPivLu().solve(even + U);
}

Matrix pade13(const Matrix& A) {
  const auto& b = kPade13;
  const Eigen::Index n = A.rows();
  const Matrix identity = Matrix::Identity(n, n);
  const Matrix A2 = A * A;
  const Matrix A4 = A2 * A2;
  const Matrix A6 = A4 * A2;
  const Matrix U =
      A * (A6 * (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * identity);
  const Matrix V = A6 * (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * identity;
  return (V - U).partialPivLu().solve(V + U);
}

ComplexPolynomial complex_poly_from_roots(const std::vector<Complex>& roots) {
  ComplexPolynomial p{Complex(1.0, 0.0)};
  for (const Complex& r : roots) {
    // p(x) (x - r): shift and subtract.
    p.push_back(Complex(0.0, 0.0));
    for (std::size_t i = p.size() - 1; i > 0; --i) p[i] -= r * p[i - 1];
  }
  return p;
}

std::vector<double> real_part(const ComplexPolynomial& p) {
  std::vector<double> out;
  out.reserve(p.size());
  for (const Complex& c : p) out.push_back(c.real());
  return out;
}

std::vector<double> multiply(const std::vector<double>& p, const std::vector<double>& q) {
  std::vector<double> out(p.size() + q.size() - 1, 0.0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (std::size_t j = 0; j < q.size(); ++j) out[i + j] += p[i] * q[j];
  }
  return out;
}

/// The bilinear scale c of s = c (z-1)/(z+1): 2/T, or w/tan(wT/2) with prewarp at w.
double tustin_scale(double T, std::optional<double> prewarp_rad_s) {
  if (prewarp_rad_s && *prewarp_rad_s > 0.0) return *prewarp_rad_s / std::tan(0.5 * *prewarp_rad_s * T);
  return 2.0 / T;
}

std::complex<double> evaluate(const std::vector<double>& p, std::complex<double> x) {
  std::complex<double> value = 0.0;
  for (double c : p) value = value * x + c;  // Horner, descending powers
  return value;
}

bool at_origin(const Complex& root) { return std::abs(root) <= kOriginTolerance; }

}  // namespace

Matrix expm(const Matrix& M) {
  const Eigen::Index n = M.rows();
  if (n == 0) return Matrix(0, 0);
  // Higham (2005), Algorithm 2.3: pick the lowest Padé degree accurate for ||M||_1, else
  // scale by 2^-s into the [13/13] range and square s times.
  const double norm = M.cwiseAbs().colwise().sum().maxCoeff();
  if (!std::isfinite(norm)) return Matrix::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  if (norm <= kTheta3) return pade_low_order(M, kPade3);
  if (norm <= kTheta5) return pade_low_order(M, kPade5);
  if (norm <= kTheta7) return pade_low_order(M, kPade7);
  if (norm <= kTheta9) return pade_low_order(M, kPade9);
  const int squarings = std::max(0, static_cast<int>(std::ceil(std::log2(norm / kTheta13))));
  Matrix result = pade13(M / std::ldexp(1.0, squarings));
  for (int i = 0; i < squarings; ++i) result = result * result;
  return result;
}

DiscreteSystem zoh(const Matrix& A, const Matrix& B, double T) {
  // exp([[A, B], [0, 0]] T) = [[Ad, Bd], [0, I]], Bd = integral_0^T e^{A s} ds B.
  const Eigen::Index n = A.rows();
  const Eigen::Index m = B.cols();
  Matrix augmented = Matrix::Zero(n + m, n + m);
  augmented.topLeftCorner(n, n) = A * T;
  augmented.topRightCorner(n, m) = B * T;
  const Matrix e = expm(augmented);
  return {e.topLeftCorner(n, n), e.topRightCorner(n, m)};
}

DiscreteNoise van_loan(const Matrix& A, const Matrix& G, const Matrix& Qc, double T) {
  // Van Loan (1978), Theorem 1: exp([[-A, G Qc G'], [0, A']] T) = [[F11, F12], [0, F22]] with
  // F22 = e^{A'T} and F12 = e^{-AT} Qd, so Ad = F22' and Qd = F22' F12.
  const Eigen::Index n = A.rows();
  Matrix C = Matrix::Zero(2 * n, 2 * n);
  C.topLeftCorner(n, n) = -A * T;
  C.topRightCorner(n, n) = G * Qc * G.transpose() * T;
  C.bottomRightCorner(n, n) = A.transpose() * T;
  const Matrix F = expm(C);
  DiscreteNoise out;
  out.Ad = F.bottomRightCorner(n, n).transpose();
  const Matrix Qd = out.Ad * F.topRightCorner(n, n);
  out.Qd = 0.5 * (Qd + Qd.transpose());  // symmetric by construction; remove rounding asymmetry
  return out;
}

std::vector<double> poly_from_roots(const std::vector<std::complex<double>>& roots) {
  return real_part(complex_poly_from_roots(roots));
}

std::vector<std::complex<double>> poly_roots(const std::vector<double>& coefficients) {
  std::size_t first = 0;
  while (first < coefficients.size() && coefficients[first] == 0.0) ++first;
  if (first + 1 >= coefficients.size()) return {};
  const auto degree = static_cast<Eigen::Index>(coefficients.size() - first - 1);
  // Eigenvalues of the companion matrix of the monic polynomial.
  Matrix companion = Matrix::Zero(degree, degree);
  for (Eigen::Index j = 0; j < degree; ++j) {
    companion(0, j) = -coefficients[first + 1 + static_cast<std::size_t>(j)] / coefficients[first];
  }
  for (Eigen::Index i = 1; i < degree; ++i) companion(i, i - 1) = 1.0;
  Eigen::EigenSolver<Matrix> solver(companion, false);
  std::vector<std::complex<double>> roots;
  for (Eigen::Index i = 0; i < degree; ++i) roots.push_back(solver.eigenvalues()(i));
  std::sort(roots.begin(), roots.end(), [](const Complex& a, const Complex& b) {
    return a.real() != b.real() ? a.real() > b.real() : a.imag() > b.imag();
  });
  return roots;
}

TransferFunction tustin(const TransferFunction& continuous, double T, std::optional<double> prewarp_rad_s) {
  // s = c (z-1)/(z+1); multiply numerator and denominator by (z+1)^N, N = the larger degree:
  // sum_i p_i s^{d-i} -> sum_i p_i c^{d-i} (z-1)^{d-i} (z+1)^{N-d+i}.
  const double c = tustin_scale(T, prewarp_rad_s);
  const std::size_t order = std::max(continuous.num.size(), continuous.den.size()) - 1;
  auto map = [&](const std::vector<double>& p) {
    std::vector<double> out(order + 1, 0.0);
    const std::size_t degree = p.size() - 1;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const std::size_t power = degree - i;  // of s
      std::vector<double> term{p[i] * std::pow(c, static_cast<double>(power))};
      for (std::size_t k = 0; k < power; ++k) term = multiply(term, {1.0, -1.0});
      for (std::size_t k = 0; k < order - power; ++k) term = multiply(term, {1.0, 1.0});
      for (std::size_t k = 0; k <= order; ++k) out[k] += term[k];
    }
    return out;
  };
  if (continuous.num.empty() || continuous.den.empty()) return {};
  TransferFunction out{map(continuous.num), map(continuous.den)};
  const double lead = out.den.front();
  if (lead != 0.0) {
    for (double& v : out.num) v /= lead;
    for (double& v : out.den) v /= lead;
  }
  return out;
}

TransferFunction tustin(const Zpk& continuous, double T, std::optional<double> prewarp_rad_s) {
  // Root by root: (s - a) = (c - a) (z - (c + a)/(c - a)) / (z + 1); the surplus of poles
  // over zeros leaves (z + 1) factors in the numerator (zeros at s = infinity -> z = -1).
  const double c = tustin_scale(T, prewarp_rad_s);
  Complex gain(continuous.gain, 0.0);
  std::vector<Complex> zeros_z;
  std::vector<Complex> poles_z;
  for (const Complex& z : continuous.zeros) {
    zeros_z.push_back((c + z) / (c - z));
    gain *= c - z;
  }
  for (const Complex& p : continuous.poles) {
    poles_z.push_back((c + p) / (c - p));
    gain /= c - p;
  }
  for (std::size_t i = continuous.zeros.size(); i < continuous.poles.size(); ++i) zeros_z.emplace_back(-1.0, 0.0);
  for (std::size_t i = continuous.poles.size(); i < continuous.zeros.size(); ++i) poles_z.emplace_back(-1.0, 0.0);
  TransferFunction out{poly_from_roots(zeros_z), poly_from_roots(poles_z)};
  for (double& v : out.num) v *= gain.real();
  return out;
}

TransferFunction matched_pole_zero(const Zpk& continuous, double T) {
  // z = e^{sT} for every finite zero and pole; zeros at s = infinity go to z = -1
  // (Franklin, Powell & Workman, Digital Control, §6.3.3).
  std::vector<Complex> zeros_z;
  std::vector<Complex> poles_z;
  for (const Complex& z : continuous.zeros) zeros_z.push_back(at_origin(z) ? Complex(1.0, 0.0) : std::exp(z * T));
  for (const Complex& p : continuous.poles) poles_z.push_back(at_origin(p) ? Complex(1.0, 0.0) : std::exp(p * T));
  const std::size_t zeros_at_infinity =
      continuous.poles.size() > continuous.zeros.size() ? continuous.poles.size() - continuous.zeros.size() : 0;
  for (std::size_t i = 0; i < zeros_at_infinity; ++i) zeros_z.emplace_back(-1.0, 0.0);

  // Gain: with k = (poles at 0) - (zeros at 0), D(s) = s^-k D~(s) and D(z) = (z-1)^-k D~(z);
  // match lim s^k D(s) = D~(0) with lim ((z-1)/T)^k D(z) = T^-k D~(z = 1).
  int k = 0;
  Complex low_frequency(continuous.gain, 0.0);  // D~(0) over the roots off the origin
  Complex discrete(1.0, 0.0);                   // D~(z = 1) / K_d over the same roots and z = -1
  for (const Complex& z : continuous.zeros) {
    if (at_origin(z)) {
      --k;
    } else {
      low_frequency *= -z;
      discrete *= 1.0 - std::exp(z * T);
    }
  }
  for (const Complex& p : continuous.poles) {
    if (at_origin(p)) {
      ++k;
    } else {
      low_frequency /= -p;
      discrete /= 1.0 - std::exp(p * T);
    }
  }
  discrete *= std::pow(2.0, static_cast<double>(zeros_at_infinity));
  const double discrete_gain = (low_frequency * std::pow(T, k) / discrete).real();
  TransferFunction out{poly_from_roots(zeros_z), poly_from_roots(poles_z)};
  for (double& v : out.num) v *= discrete_gain;
  return out;
}

std::complex<double> discrete_response(const TransferFunction& tf, double w_rad_s, double T) {
  const std::complex<double> z = std::exp(std::complex<double>(0.0, w_rad_s * T));
  return evaluate(tf.num, z) / evaluate(tf.den, z);
}

std::complex<double> continuous_response(const TransferFunction& tf, double w_rad_s) {
  const std::complex<double> s(0.0, w_rad_s);
  return evaluate(tf.num, s) / evaluate(tf.den, s);
}

}  // namespace lode::math
