// Discrete algebraic Riccati equations: LQ regulators and steady-state Kalman gains.
// Configure-time only. Checked against SLICOT SB02OD in tests/core/riccati_test.cpp.
#pragma once

#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/status.hpp"

namespace lode::math {

/// The stabilising solution P of
///   P = A'PA - (A'PB + N)(R + B'PB)^-1 (B'PA + N') + Q
/// (N optional cross weight). Fails with a message when (A, B) is not stabilisable, the
/// solution is not found to `tolerance`, or R + B'PB is not positive definite.
/// Method (core/src/math/riccati.cpp): states balanced by powers of two, structured doubling
/// until the relative change of P is <= `tolerance`, Newton-Hewer from a stabilising gain if
/// the doubling result does not stabilise (Q blind to an unstable mode), then Newton defect
/// correction; accepted when A - BK is stable and the relative residual (DareSolution) is
/// <= 1e3 max(tolerance, 64 eps). R must be positive definite.
Expected<Matrix> solve_dare(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R,
                            const Matrix* N = nullptr, double tolerance = 1e-12);

/// solve_dare() with the figures of merit of the solve (for tests and describe()).
struct DareSolution {
  Matrix P;
  /// ||residual||_F / (||P||_F + ||A'PA||_F + ||(A'PB+N)(R+B'PB)^-1(B'PA+N')||_F + ||Q||_F):
  /// a backward error, of the order of the machine epsilon for a well-solved equation.
  double relative_residual = 0.0;
  int doubling_steps = 0;     ///< structured-doubling iterations
  int newton_steps = 0;       ///< Newton defect-correction steps accepted afterwards
  double spectral_radius = 0.0;  ///< of the closed loop A - B K (< 1: stabilising)
};
Expected<DareSolution> solve_dare_detailed(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R,
                                           const Matrix* N = nullptr, double tolerance = 1e-12);

/// Discrete LQ regulator u = -K x minimising sum x'Qx + u'Ru (+ 2x'Nu).
struct Lqr {
  Matrix K;
  Matrix P;
  Eigen::VectorXcd closed_loop_poles;  ///< eigenvalues of A - B K
};
Expected<Lqr> dlqr(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R,
                   const Matrix* N = nullptr);

/// Steady-state Kalman filter for x_{k+1} = A x_k + w, y_k = C x_k + v, E[ww'] = Q,
/// E[vv'] = R (Q already in state coordinates, e.g. Ups Qk Ups').
struct SteadyKalman {
  Matrix K;        ///< measurement-update gain P_prior C' (C P_prior C' + R)^-1
  Matrix P_prior;  ///< a-priori covariance (the DARE solution of the dual problem)
  Matrix P_post;   ///< (I - K C) P_prior
};
Expected<SteadyKalman> steady_state_kalman(const Matrix& A, const Matrix& C, const Matrix& Q,
                                           const Matrix& R);

}  // namespace lode::math
