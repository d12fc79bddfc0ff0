// Discrete algebraic Riccati equations: LQ regulators and steady-state Kalman gains.
// Configure-time only. Checked against SLICOT SB02OD in tests/core/riccati_test.cpp.
#pragma once

#include "lode/math/discretize.hpp"
#include "lode/status.hpp"

namespace lode::math {

/// The stabilising solution P of
///   P = A'PA - (A'PB + N)(R + B'PB)^-1 (B'PA + N') + Q
/// (N optional cross weight). Fails with a message when (A, B) is not stabilisable, the
/// solution is not found to `tolerance`, or R + B'PB is not positive definite.
Expected<Matrix> solve_dare(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R,
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
