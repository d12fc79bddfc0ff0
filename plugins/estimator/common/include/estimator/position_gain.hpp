// The filters that measure the position state alone (H = [1 0 ... 0]: estimator.kalman,
// estimator.hybrid_h2hinf, estimator.ekf_encoder's position-equivalent form) share these pieces
// of their update and of their steady-state (Riccati) designs. i_minus_kh() is RT-safe (fixed
// sizes, no allocation); the rest serves describe() and design code off the RT thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <complex>
#include <cstddef>

namespace lode::plugins::estimator {

/// I - K H with H = [1 0 ... 0]: K H has the gain as its first column and zeros elsewhere.
template <typename Derived>
Eigen::Matrix<double, Derived::RowsAtCompileTime, Derived::RowsAtCompileTime> i_minus_kh(
    const Eigen::MatrixBase<Derived>& gain) noexcept {
  constexpr int kStates = Derived::RowsAtCompileTime;
  Eigen::Matrix<double, kStates, kStates> out = Eigen::Matrix<double, kStates, kStates>::Identity();
  out.col(0) -= gain;
  return out;
}

/// True when no element of `now` differs from `before` by more than `relative_tolerance` times
/// its own size (false as soon as one does, or is not finite): when a Riccati iteration stops,
/// on its gains or on its standard deviations.
template <typename Now, typename Before>
bool settled(const Eigen::MatrixBase<Now>& now, const Eigen::MatrixBase<Before>& before,
             double relative_tolerance) {
  for (Eigen::Index i = 0; i < now.size(); ++i) {
    if (!(std::abs(now(i) - before(i)) <= relative_tolerance * std::abs(now(i)))) return false;
  }
  return true;
}

/// The eigenvalues z of the a-priori error dynamics Phi (I - K H), as (re, im): the poles of a
/// steady-state position filter. All zero when Phi (I - K H) is not finite (no design).
template <int N>
std::array<std::array<double, 2>, N> error_poles(const Eigen::Matrix<double, N, N>& phi,
                                                 const Eigen::Matrix<double, N, 1>& gain) {
  std::array<std::array<double, 2>, N> poles{};
  const Eigen::Matrix<double, N, N> error_dynamics = phi * i_minus_kh(gain);
  if (error_dynamics.allFinite()) {
    Eigen::EigenSolver<Eigen::Matrix<double, N, N>> solver(error_dynamics, false);
    for (int i = 0; i < N; ++i) {
      const std::complex<double> z = solver.eigenvalues()(i);
      poles[static_cast<std::size_t>(i)] = {z.real(), z.imag()};
    }
  }
  return poles;
}

}  // namespace lode::plugins::estimator
