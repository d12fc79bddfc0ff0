// Discrete algebraic Riccati equation: structured doubling, then Newton defect correction.
//
// Method (Chu, Fan, Lin & Wang 2004, "Structure-preserving algorithms for periodic discrete-time
// algebraic Riccati equations", and Lin & Xu 2006 for convergence): with G = B R^-1 B' the DARE
//   P = A'PA - A'PB (R + B'PB)^-1 B'PA + Q  is  P = A' P (I + G P)^-1 A + Q,
// and the doubling recursion from A_0 = A, G_0 = G, H_0 = Q,
//   W_k = I + G_k H_k
//   A_{k+1} = A_k W_k^-1 A_k
//   G_{k+1} = G_k + A_k W_k^-1 G_k A_k'
//   H_{k+1} = H_k + A_k' H_k W_k^-1 A_k
// converges quadratically to H_inf = P whenever the symplectic pencil has no eigenvalue on the
// unit circle ((A, B) stabilisable, no unobservable mode of (Q, A) on the unit circle). It needs
// neither A nor the pencil's second matrix to be invertible (unlike the Schur method on the
// symplectic matrix) and preserves symmetry. A cross weight N is removed first by
//   A~ = A - B R^-1 N',  Q~ = Q - N R^-1 N'.
// The doubling result is then polished by Newton's method in defect-correction form
// (Hewer 1971): X - Acl' X Acl = Res(P), P <- P + X, accepted while the residual falls.
//
// Two safeguards around the doubling:
// - The states are first balanced by powers of two (Parlett & Reinsch 1969 on A, exact in
//   floating point): x = D x~ gives A~ = D^-1 A D, B~ = D^-1 B, Q~ = D Q D, N~ = D N and
//   P = D^-1 P~ D^-1, so states scaled 1e-6 ... 1e6 cost no accuracy.
// - Doubling from H_0 = Q is the Riccati recursion from P_0 = 0 sped up; when an unstable mode
//   is not seen by Q (Q = 0 on an unstable plant, say) it converges to a non-stabilising
//   solution. Then the stabilising one is reached by Newton-Hewer iteration from the gain of
//   the problem with Q + delta I (which is detectable), each step solving the Stein equation
//   P = Acl' P Acl + Q - N K - K'N' + K'RK for the current gain K.
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "lode/sdk/math/riccati.hpp"
#include "lode/sdk/text.hpp"

namespace lode::math {

namespace {

constexpr int kMaxDoublingSteps = 100;
constexpr int kMaxNewtonSteps = 6;
/// Stein equations up to this order are solved directly through their n^2 x n^2 Kronecker
/// form; larger ones by Smith's doubling.
constexpr Eigen::Index kMaxKroneckerOrder = 24;
/// A residual this small (relative, see DareSolution) is at the rounding level: stop polishing.
constexpr double kRoundingResidual = 64.0 * std::numeric_limits<double>::epsilon();
/// PBH test threshold: sigma_min([A - lambda I, B]) below this times ||[A B]|| = unreachable.
constexpr double kUnreachable = 1e-13;

double norm_1(const Matrix& M) { return M.size() == 0 ? 0.0 : M.cwiseAbs().colwise().sum().maxCoeff(); }

Matrix symmetric(const Matrix& M) { return 0.5 * (M + M.transpose()); }

bool finite(const Matrix& M) { return M.allFinite(); }

/// The DARE at P: the gain K = (R + B'PB)^-1 (B'PA + N') and the residual.
struct Evaluation {
  Matrix K;
  Matrix residual;
  double relative_residual = 0.0;
  bool gram_positive = false;  ///< R + B'PB positive definite
};

Evaluation evaluate(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R, const Matrix* N,
                    const Matrix& P) {
  Evaluation e;
  const Matrix gram = symmetric(R + B.transpose() * P * B);
  Matrix cross = B.transpose() * P * A;  // m x n: B'PA + N'
  if (N != nullptr) cross += N->transpose();
  Eigen::LLT<Matrix> llt(gram);
  e.gram_positive = llt.info() == Eigen::Success;
  e.K = e.gram_positive ? Matrix(llt.solve(cross)) : Matrix(gram.partialPivLu().solve(cross));
  const Matrix propagated = A.transpose() * P * A;
  const Matrix quadratic = cross.transpose() * e.K;
  e.residual = symmetric(propagated - quadratic + Q - P);
  const double scale = P.norm() + propagated.norm() + quadratic.norm() + Q.norm();
  e.relative_residual = scale > 0.0 ? e.residual.norm() / scale : e.residual.norm();
  if (!std::isfinite(e.relative_residual)) e.relative_residual = std::numeric_limits<double>::infinity();
  return e;
}

/// X - F' X F = C for a stable F (Stein / discrete Lyapunov equation).
Matrix solve_stein(const Matrix& F, const Matrix& C) {
  const Eigen::Index n = F.rows();
  if (n <= kMaxKroneckerOrder) {
    // vec(F' X F) = (F' (x) F') vec(X), column-major vec index i + n j.
    const Eigen::Index nn = n * n;
    Matrix system = Matrix::Identity(nn, nn);
    for (Eigen::Index j1 = 0; j1 < n; ++j1) {
      for (Eigen::Index i1 = 0; i1 < n; ++i1) {
        for (Eigen::Index j2 = 0; j2 < n; ++j2) {
          for (Eigen::Index i2 = 0; i2 < n; ++i2) {
            system(i1 + n * j1, i2 + n * j2) -= F(j2, j1) * F(i2, i1);
          }
        }
      }
    }
    const Vector rhs = Eigen::Map<const Vector>(C.data(), nn);
    const Vector x = system.partialPivLu().solve(rhs);
    return symmetric(Eigen::Map<const Matrix>(x.data(), n, n));
  }
  // Smith: X = sum_k (F')^k C F^k, doubled: X <- X + M' X M, M <- M^2.
  Matrix X = C;
  Matrix M = F;
  for (int step = 0; step < 64; ++step) {
    const Matrix increment = M.transpose() * X * M;
    X += increment;
    M = M * M;
    if (increment.norm() <= std::numeric_limits<double>::epsilon() * X.norm()) break;
  }
  return symmetric(X);
}

/// Diagonal D (powers of two) with D^-1 A D balanced: row and column norms of the off-diagonal
/// part within a factor of two (Parlett & Reinsch 1969, as LAPACK dgebal without permutations).
Vector balancing_scale(const Matrix& A_in) {
  Matrix A = A_in;
  const Eigen::Index n = A.rows();
  Vector d = Vector::Ones(n);
  for (int sweep = 0; sweep < 100; ++sweep) {
    bool changed = false;
    for (Eigen::Index i = 0; i < n; ++i) {
      double column = 0.0;
      double row = 0.0;
      for (Eigen::Index j = 0; j < n; ++j) {
        if (j == i) continue;
        column += std::abs(A(j, i));
        row += std::abs(A(i, j));
      }
      if (column == 0.0 || row == 0.0) continue;
      const double total = column + row;
      double f = 1.0;
      while (column < 0.5 * row) {
        column *= 2.0;
        row *= 0.5;
        f *= 2.0;
      }
      while (column >= 2.0 * row) {
        column *= 0.5;
        row *= 2.0;
        f *= 0.5;
      }
      if (column + row < 0.95 * total) {
        d(i) *= f;
        A.col(i) *= f;
        A.row(i) /= f;
        changed = true;
      }
    }
    if (!changed) break;
  }
  return d;
}

/// The stabilising solution from a stabilising gain by Newton-Hewer iteration (no N: the cross
/// weight is already removed). Returns an empty matrix if it does not converge.
Matrix hewer(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R, Matrix K, double tolerance) {
  Matrix P;
  for (int step = 0; step < 60; ++step) {
    const Matrix closed_loop = A - B * K;
    const Matrix next = solve_stein(closed_loop, symmetric(Q + K.transpose() * R * K));
    if (!finite(next)) return {};
    const bool settled = P.size() > 0 && (next - P).norm() <= tolerance * next.norm();
    P = next;
    K = symmetric(R + B.transpose() * P * B).llt().solve(B.transpose() * P * A);
    if (settled) return P;
  }
  return {};
}

/// PBH test: an eigenvalue of A on or outside the unit circle that B cannot reach.
Status check_stabilisable(const Matrix& A, const Matrix& B) {
  const Eigen::Index n = A.rows();
  Eigen::EigenSolver<Matrix> eigen(A, false);
  if (eigen.info() != Eigen::Success) return Status::ok();  // left to the closed-loop check
  Eigen::MatrixXcd pencil(n, n + B.cols());
  double scale = 1.0;
  {
    Matrix ab(n, n + B.cols());
    ab << A, B;
    scale = std::max(1.0, ab.norm());
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::complex<double> lambda = eigen.eigenvalues()(i);
    if (std::abs(lambda) < 1.0) continue;
    pencil.leftCols(n) = A.cast<std::complex<double>>() - lambda * Eigen::MatrixXcd::Identity(n, n);
    pencil.rightCols(B.cols()) = B.cast<std::complex<double>>();
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(pencil);
    const double smallest = svd.singularValues()(n - 1);
    if (smallest <= kUnreachable * scale) {
      return Status::error("(A, B) is not stabilisable: the mode at z = " + number_text(lambda.real()) +
                           (lambda.imag() != 0.0 ? (lambda.imag() > 0 ? "+" : "") + number_text(lambda.imag()) + "j"
                                                 : std::string()) +
                           " (|z| = " + number_text(std::abs(lambda)) + " >= 1) is not reachable from B");
    }
  }
  return Status::ok();
}

Status check_shapes(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R, const Matrix* N) {
  const Eigen::Index n = A.rows();
  const Eigen::Index m = B.cols();
  auto size = [](const Matrix& M) { return std::to_string(M.rows()) + "x" + std::to_string(M.cols()); };
  if (n == 0 || A.cols() != n) return Status::error("A must be square and non-empty, got " + size(A));
  if (B.rows() != n || m == 0) return Status::error("B must have " + std::to_string(n) + " rows, got " + size(B));
  if (Q.rows() != n || Q.cols() != n) return Status::error("Q must be " + size(A) + ", got " + size(Q));
  if (R.rows() != m || R.cols() != m) {
    return Status::error("R must be " + std::to_string(m) + "x" + std::to_string(m) + ", got " + size(R));
  }
  if (N != nullptr && (N->rows() != n || N->cols() != m)) {
    return Status::error("N must be " + size(B) + ", got " + size(*N));
  }
  if (!finite(A) || !finite(B) || !finite(Q) || !finite(R) || (N != nullptr && !finite(*N))) {
    return Status::error("A, B, Q, R and N must be finite");
  }
  return Status::ok();
}

}  // namespace

namespace {

/// Structured doubling for P = A' P (I + G P)^-1 A + H (see the file comment).
struct Doubling {
  Matrix P;
  int steps = 0;
  bool converged = false;
  bool diverged = false;
};

Doubling structured_doubling(const Matrix& A, const Matrix& G, const Matrix& H, double tolerance) {
  const Eigen::Index n = A.rows();
  // Scale P = sigma X so that ||sigma G|| = ||H / sigma||: the doubling then works on matrices
  // of comparable size however R and Q are weighted (tiny R: ||G|| ~ 1e10).
  const double g_norm = norm_1(G);
  const double h_norm = norm_1(H);
  const double sigma = g_norm > 0.0 && h_norm > 0.0 ? std::sqrt(h_norm / g_norm) : 1.0;
  Matrix Ak = A;
  Matrix Gk = sigma * G;
  Matrix Hk = H / sigma;
  const Matrix identity = Matrix::Identity(n, n);
  Doubling out;
  for (int step = 1; step <= kMaxDoublingSteps; ++step) {
    Eigen::PartialPivLU<Matrix> w(identity + Gk * Hk);
    const Matrix w_inv_a = w.solve(Ak);  // W^-1 A_k
    const Matrix w_inv_g = w.solve(Gk);  // W^-1 G_k (symmetric in exact arithmetic)
    const Matrix next_h = symmetric(Hk + Ak.transpose() * Hk * w_inv_a);
    const Matrix next_g = symmetric(Gk + Ak * w_inv_g * Ak.transpose());
    const Matrix next_a = Ak * w_inv_a;
    out.steps = step;
    if (!finite(next_h) || !finite(next_g) || !finite(next_a)) {
      out.diverged = true;
      return out;
    }
    const double change = norm_1(next_h - Hk);
    Ak = next_a;
    Gk = next_g;
    Hk = next_h;
    if (change <= tolerance * norm_1(Hk)) {
      out.converged = true;
      break;
    }
  }
  out.P = sigma * Hk;
  return out;
}

/// The closed loop of (A, B) under the gain of P (no cross weight), and its spectral radius.
double closed_loop_radius(const Matrix& A, const Matrix& B, const Matrix& R, const Matrix& P, Matrix* gain) {
  const Matrix K = symmetric(R + B.transpose() * P * B).llt().solve(B.transpose() * P * A);
  if (gain != nullptr) *gain = K;
  if (!finite(K)) return std::numeric_limits<double>::infinity();
  return Eigen::EigenSolver<Matrix>(A - B * K, false).eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace

Expected<DareSolution> solve_dare_detailed(const Matrix& A, const Matrix& B, const Matrix& Q_in, const Matrix& R_in,
                                           const Matrix* N, double tolerance) {
  if (Status s = check_shapes(A, B, Q_in, R_in, N); !s) return s;
  const Eigen::Index n = A.rows();
  const Matrix Q = symmetric(Q_in);
  const Matrix R = symmetric(R_in);

  Eigen::LLT<Matrix> r_factor(R);
  if (r_factor.info() != Eigen::Success) {
    const double smallest = Eigen::SelfAdjointEigenSolver<Matrix>(R, Eigen::EigenvaluesOnly).eigenvalues()(0);
    return Status::error("R must be positive definite (smallest eigenvalue " + number_text(smallest) + ")");
  }

  // Balance the states: x = D x~ (D powers of two, so the transformation itself is exact).
  const Vector d = balancing_scale(A);
  const Vector d_inv = d.cwiseInverse();
  const Matrix Ab = d_inv.asDiagonal() * A * d.asDiagonal();
  const Matrix Bb = d_inv.asDiagonal() * B;
  const Matrix Qb = d.asDiagonal() * Q * d.asDiagonal();
  Matrix Nb;
  if (N != nullptr) Nb = d.asDiagonal() * *N;
  const Matrix* Nb_ptr = N != nullptr ? &Nb : nullptr;
  if (Status s = check_stabilisable(Ab, Bb); !s) return s;

  // Remove the cross weight: u = v - R^-1 N' x turns (A, Q, N) into (A0, H0, 0).
  Matrix A0 = Ab;
  Matrix H0 = Qb;
  if (N != nullptr) {
    const Matrix r_inv_nt = r_factor.solve(Nb.transpose());  // m x n
    A0 = Ab - Bb * r_inv_nt;
    H0 = symmetric(Qb - Nb * r_inv_nt);
  }
  // G = B R^-1 B' = (B L^-T)(B L^-T)' from R = L L': symmetric and PSD by construction, even
  // when R is tiny or badly conditioned.
  const Matrix b_l = r_factor.matrixL().solve(Bb.transpose()).transpose();  // B L^-T
  const Matrix G0 = b_l * b_l.transpose();

  DareSolution out;
  Doubling doubling = structured_doubling(A0, G0, H0, tolerance);
  out.doubling_steps = doubling.steps;
  Matrix Pb = doubling.P;
  if (doubling.diverged) {
    return Status::error("the doubling iteration diverged at step " + std::to_string(doubling.steps) +
                         ": no stabilising solution ((A, B) not stabilisable?)");
  }
  if (!doubling.converged || !(closed_loop_radius(A0, Bb, R, Pb, nullptr) < 1.0)) {
    // An unstable or marginal mode that Q does not see (or slow convergence near the unit
    // circle): start Newton-Hewer from the gain of the detectable problem Q + delta I.
    // delta is small against ||Q|| and against 1/||G|| (the scale of P when Q is tiny).
    const double g_norm = norm_1(G0);
    const double delta = 1e-6 * (norm_1(H0) + (g_norm > 0.0 ? 1.0 / g_norm : 1.0));
    Doubling regularised = structured_doubling(A0, G0, symmetric(H0 + delta * Matrix::Identity(n, n)), tolerance);
    Matrix K0;
    if (regularised.diverged || !regularised.converged ||
        !(closed_loop_radius(A0, Bb, R, regularised.P, &K0) < 1.0)) {
      return Status::error("no stabilising solution: the doubling iteration did not converge to " +
                           number_text(tolerance) + " in " + std::to_string(kMaxDoublingSteps) +
                           " steps (is every unstable mode reachable from B?)");
    }
    Pb = hewer(A0, Bb, H0, R, K0, tolerance);
    if (Pb.size() == 0) {
      return Status::error("no stabilising solution: Newton-Hewer iteration did not converge (a closed-loop mode "
                           "on the unit circle: a marginal mode of A that Q does not weight?)");
    }
  }

  // Newton defect correction on the balanced equation (with N).
  Evaluation e = evaluate(Ab, Bb, Qb, R, Nb_ptr, Pb);
  for (int step = 0; step < kMaxNewtonSteps && e.relative_residual > kRoundingResidual; ++step) {
    const Matrix closed_loop = Ab - Bb * e.K;
    const Matrix candidate = symmetric(Pb + solve_stein(closed_loop, e.residual));
    if (!finite(candidate)) break;
    Evaluation candidate_e = evaluate(Ab, Bb, Qb, R, Nb_ptr, candidate);
    if (!(candidate_e.relative_residual < e.relative_residual)) break;
    Pb = candidate;
    e = std::move(candidate_e);
    ++out.newton_steps;
  }

  // Back to the caller's coordinates; every check on the original equation.
  Matrix P = symmetric(d_inv.asDiagonal() * Pb * d_inv.asDiagonal());
  e = evaluate(A, B, Q, R, N, P);
  if (!e.gram_positive) return Status::error("R + B'PB is not positive definite at the solution");
  const Eigen::VectorXcd poles = Eigen::EigenSolver<Matrix>(A - B * e.K, false).eigenvalues();
  out.spectral_radius = poles.cwiseAbs().maxCoeff();
  if (!(out.spectral_radius < 1.0)) {
    return Status::error("no stabilising solution: the closed loop A - BK has a pole at |z| = " +
                         number_text(out.spectral_radius) +
                         " (a marginal or unstable mode is not reachable from B or not weighted by Q)");
  }
  out.relative_residual = e.relative_residual;
  const double allowed = 1e3 * std::max(tolerance, kRoundingResidual);
  if (!(out.relative_residual <= allowed)) {
    return Status::error("the Riccati residual " + number_text(out.relative_residual) + " exceeds " +
                         number_text(allowed) + " (relative)");
  }
  out.P = std::move(P);
  return out;
}

Expected<Matrix> solve_dare(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R, const Matrix* N,
                            double tolerance) {
  Expected<DareSolution> solution = solve_dare_detailed(A, B, Q, R, N, tolerance);
  if (!solution) return solution.status();
  return std::move(solution->P);
}

Expected<Lqr> dlqr(const Matrix& A, const Matrix& B, const Matrix& Q, const Matrix& R, const Matrix* N) {
  Expected<Matrix> P = solve_dare(A, B, Q, R, N);
  if (!P) return P.status();
  Lqr out;
  Matrix cross = B.transpose() * *P * A;
  if (N != nullptr) cross += N->transpose();
  out.K = symmetric(R + B.transpose() * *P * B).llt().solve(cross);
  out.P = std::move(*P);
  out.closed_loop_poles = Eigen::EigenSolver<Matrix>(A - B * out.K, false).eigenvalues();
  return out;
}

Expected<SteadyKalman> steady_state_kalman(const Matrix& A, const Matrix& C, const Matrix& Q, const Matrix& R) {
  // The filter's a-priori covariance solves the dual DARE (A', C', Q, R):
  //   P = A P A' - A P C' (C P C' + R)^-1 C P A' + Q.
  if (C.cols() != A.rows()) {
    return Status::error("C must have " + std::to_string(A.rows()) + " columns, got " + std::to_string(C.cols()));
  }
  Expected<Matrix> P = solve_dare(A.transpose(), C.transpose(), Q, R);
  if (!P) return Status::error("steady-state Kalman filter: " + P.error());
  SteadyKalman out;
  out.P_prior = std::move(*P);
  const Matrix innovation = symmetric(C * out.P_prior * C.transpose() + R);
  out.K = innovation.llt().solve(C * out.P_prior).transpose();  // P C' S^-1 (S symmetric)
  const Matrix identity = Matrix::Identity(A.rows(), A.rows());
  out.P_post = symmetric((identity - out.K * C) * out.P_prior);
  return out;
}

}  // namespace lode::math
