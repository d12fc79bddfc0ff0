// The classical fourth-order Runge-Kutta step (Kutta 1901), input held over the step, for the
// plants that integrate an ODE (plant.rigid_body6, plant.suspension). One formula in one
// operation order, so a plant's simulator (advance()) and its process model (propagate())
// round alike, step for step.
//
// RT-safe: fixed-size arrays, no allocation, no throw (as long as the derivative is).
#pragma once

#include <array>
#include <cstddef>

namespace lode::plugins::plants {

/// One step of dx/dt = f(x) of length h:
///   k1 = f(x), k2 = f(x + h/2 k1), k3 = f(x + h/2 k2), k4 = f(x + h k3),
///   x_next = x + h/6 (k1 + 2 k2 + 2 k3 + k4).
/// `derivative(at, slope)` writes f(at) into slope. x_next may be x itself.
template <std::size_t N, typename Derivative>
void rk4_step(const std::array<double, N>& x, double h, const Derivative& derivative,
              std::array<double, N>& x_next) noexcept {
  std::array<double, N> k1, k2, k3, k4, at;
  derivative(x, k1);
  for (std::size_t i = 0; i < N; ++i) at[i] = x[i] + 0.5 * h * k1[i];
  derivative(at, k2);
  for (std::size_t i = 0; i < N; ++i) at[i] = x[i] + 0.5 * h * k2[i];
  derivative(at, k3);
  for (std::size_t i = 0; i < N; ++i) at[i] = x[i] + h * k3[i];
  derivative(at, k4);
  for (std::size_t i = 0; i < N; ++i) {
    x_next[i] = x[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
  }
}

}  // namespace lode::plugins::plants
