// Continuous-to-discrete conversions, used at configure time (dynamic Eigen is fine here;
// results are copied into fixed-size members for the cycle).
//
// Every routine is double precision and documented with the formula it implements.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <optional>
#include <vector>

namespace lode::math {

using Matrix = Eigen::MatrixXd;
using Vector = Eigen::VectorXd;

/// Matrix exponential e^M (scaling and squaring with a [13/13] Padé approximant, Higham 2005).
Matrix expm(const Matrix& M);

/// Zero-order hold of x' = A x + B u over T: x_{k+1} = Ad x_k + Bd u_k, from
/// exp([[A, B], [0, 0]] T) = [[Ad, Bd], [0, I]].
struct DiscreteSystem {
  Matrix Ad;
  Matrix Bd;
};
DiscreteSystem zoh(const Matrix& A, const Matrix& B, double T);

/// Van Loan (1978): for x' = A x + G w, E[w w'] = Qc delta(t), the discrete process noise
/// Qd = integral_0^T e^{A s} G Qc G' e^{A' s} ds and Ad = e^{A T}.
struct DiscreteNoise {
  Matrix Ad;
  Matrix Qd;
};
DiscreteNoise van_loan(const Matrix& A, const Matrix& G, const Matrix& Qc, double T);

/// A rational function num/den, coefficients in descending powers (of s or z).
struct TransferFunction {
  std::vector<double> num;
  std::vector<double> den;
};

/// Zeros, poles and gain: D(s) = gain * prod(s - z_i) / prod(s - p_i).
struct Zpk {
  std::vector<std::complex<double>> zeros;
  std::vector<std::complex<double>> poles;
  double gain = 1.0;
};

/// Monic polynomial with these roots (real coefficients; complex roots must come in pairs).
std::vector<double> poly_from_roots(const std::vector<std::complex<double>>& roots);

/// Roots of a polynomial in descending powers (leading zeros ignored): the eigenvalues of its
/// companion matrix, sorted by descending real part, then descending imaginary part.
std::vector<std::complex<double>> poly_roots(const std::vector<double>& coefficients);

/// Bilinear (Tustin) transform s = (2/T)(z-1)/(z+1); with prewarp w [rad/s] the scale is
/// w / tan(w T / 2), so the discrete response equals the continuous one exactly at w.
/// The result is normalised so den[0] = 1.
TransferFunction tustin(const TransferFunction& continuous, double T,
                        std::optional<double> prewarp_rad_s = std::nullopt);
/// The same map applied root by root, (s - a) -> (c - a)(z - (c+a)/(c-a))/(z + 1) with
/// c = 2/T or w/tan(wT/2); zeros at s = infinity go to z = -1. Better conditioned than the
/// coefficient form for high orders. num carries the gain, den[0] = 1.
TransferFunction tustin(const Zpk& continuous, double T, std::optional<double> prewarp_rad_s = std::nullopt);

/// Matched pole-zero: z = e^{sT} for every pole and zero; zeros at infinity (fewer finite
/// zeros than poles) map to z = -1; the gain matches the DC gain, or, with k poles at the
/// origin, lim s^k D(s) = lim ((z-1)/T)^k D(z) (the velocity constant for k = 1).
/// The result is normalised so den[0] = 1 (num carries the gain).
TransferFunction matched_pole_zero(const Zpk& continuous, double T);

/// Frequency response of a discrete transfer function at w [rad/s] with sample time T.
std::complex<double> discrete_response(const TransferFunction& tf, double w_rad_s, double T);

/// Frequency response of a continuous transfer function at s = j w [rad/s].
std::complex<double> continuous_response(const TransferFunction& tf, double w_rad_s);

}  // namespace lode::math
