// The core shared by the per-axis linear filters (estimator.kalman, estimator.hybrid_h2hinf):
// n <= 6 measured positions, each filtered on its own by an N-state axis
//   x = [position, velocity, acceleration] (N = 3, constant acceleration) or
//       [position, velocity]               (N = 2, constant velocity),
// with the discrete motion model of Kawato (2005, eq. 4.39), which is also Silva-Rivas & Kim
// (2013, eq. 20-23):
//   Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],  Upsilon = [T^3/6, T^2/2, T]'   (N = 3)
//   Phi = [[1, T], [0, 1]],                       Upsilon = [T^2/2, T]'          (N = 2)
// and H = [1 0 ...]. What differs between the filters, the gain (a Riccati recursion or a
// steady blend), stays in each plugin; here are the model, the sizing from the measurement,
// the outputs, and the estimator state of hot swap in the layout both export:
//   per axis <n> [u], <n>_dot [u/s] (and <n>_ddot [u/s^2] for N = 3), axis after axis, with a
//   block-diagonal covariance (the axes are independent).
//
// Threads: measured_axes(), AxisOutputs::declare() and axis_state_layout() run in configure()
// (off the RT thread, they allocate); everything else is RT-safe (fixed sizes, no allocation).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"

namespace lode::plugins::estimator {

/// The most measured axes a per-axis filter takes (a 6-DOF pose).
inline constexpr std::size_t kMaxAxes = 6;

/// Index names of the per-axis state.
inline constexpr int kPosition = 0;
inline constexpr int kVelocity = 1;
inline constexpr int kAcceleration = 2;

/// Which estimate the outputs carry: the prior of the next step x^-_{k+1} or the posterior x^+_k.
enum class OutputTiming { predicted, filtered };

/// What a non-finite measurement does to a per-axis filter.
enum class InvalidMeasurement {
  fault,   ///< the step faults, nothing changes (the default)
  predict  ///< that axis coasts on the time update for this cycle; the step succeeds
};

/// The `invalid_measurement` parameter: fault (the default) or predict.
InvalidMeasurement read_invalid_measurement(Params& params);

/// How describe() reports it.
const char* invalid_measurement_text(InvalidMeasurement invalid_measurement) noexcept;

/// Phi and Upsilon of one axis with N states (2: constant velocity, 3: constant acceleration).
template <int N>
struct MotionModel {
  static_assert(N == 2 || N == 3, "one axis has 2 (CV) or 3 (CA) states");
  using Matrix = Eigen::Matrix<double, N, N>;
  using Vector = Eigen::Matrix<double, N, 1>;

  Matrix phi = Matrix::Identity();
  Vector upsilon = Vector::Zero();

  /// Phi and Upsilon (see the file comment) for the period t_s.
  static MotionModel make(double t_s) {
    MotionModel m;
    if constexpr (N == 3) {
      m.phi << 1.0, t_s, 0.5 * t_s * t_s,  //
          0.0, 1.0, t_s,                   //
          0.0, 0.0, 1.0;
      m.upsilon << t_s * t_s * t_s / 6.0, 0.5 * t_s * t_s, t_s;
    } else {
      m.phi << 1.0, t_s,  //
          0.0, 1.0;
      m.upsilon << 0.5 * t_s * t_s, t_s;
    }
    return m;
  }
};

/// The elements of the `measurement` input, which size the filter (one axis per element) and
/// name its outputs: 1 to kMaxAxes elements with definite units. Declare the input first. Any
/// problem is reported on "inputs" and gives no axes.
Elements measured_axes(ConfigureContext& ctx);

/// The outputs of a per-axis filter, named after the measured positions:
///   pose [n], velocity <n>_dot [<u>/s], acceleration <n>_ddot [<u>/s^2] (N = 3 only),
///   innovation [n] (y_k - H x^-_k).
struct AxisOutputs {
  OutputPort pose;
  OutputPort velocity;
  OutputPort acceleration;  ///< unbound without an acceleration state
  OutputPort innovation;

  void declare(ConfigureContext& ctx, const Elements& positions, bool with_acceleration);

  /// Every output 0 on the first `axes` axes (activate()).
  void clear(std::size_t axes) noexcept {
    for (std::size_t i = 0; i < axes; ++i) {
      pose[i] = 0.0;
      velocity[i] = 0.0;
      if (acceleration.bound()) acceleration[i] = 0.0;
      innovation[i] = 0.0;
    }
  }

  /// Axis `axis` of the state x (and its innovation, 0 on a coasting axis) to the outputs.
  template <int N>
  void write(std::size_t axis, const Eigen::Matrix<double, N, 1>& x, double innovation_value) noexcept {
    pose[axis] = x(kPosition);
    velocity[axis] = x(kVelocity);
    if constexpr (N == 3) acceleration[axis] = x(kAcceleration);
    innovation[axis] = innovation_value;
  }
};

/// The estimator-state layout: per axis <n> [u], <n>_dot [u/s] (, <n>_ddot [u/s^2]), axis
/// after axis, with a covariance.
StateLayout axis_state_layout(const Elements& positions, int states_per_axis);

/// export_state() of independent axes: axis i's state `state_of(i)` at elements i N ... i N + N - 1
/// and its covariance `covariance_of(i)` on the diagonal block there (null `covariance`: the
/// values alone); every cross-axis term is 0.
template <int N, typename StateOf, typename CovarianceOf>
void export_axes(std::size_t axes, const StateOf& state_of, const CovarianceOf& covariance_of, double* values,
                 double* covariance) noexcept {
  const std::size_t n = axes * N;
  if (covariance != nullptr) std::fill(covariance, covariance + n * n, 0.0);
  for (std::size_t i = 0; i < axes; ++i) {
    const auto& x = state_of(i);
    for (int a = 0; a < N; ++a) {
      const std::size_t row = i * N + static_cast<std::size_t>(a);
      values[row] = x(a);
      if (covariance == nullptr) continue;
      const auto& p = covariance_of(i);
      for (int b = 0; b < N; ++b) covariance[row * n + i * N + static_cast<std::size_t>(b)] = p(a, b);
    }
  }
}

/// What import_state() hands one axis, in the export_axes() layout.
template <int N>
struct ImportedAxis {
  Eigen::Matrix<double, N, 1> state = Eigen::Matrix<double, N, 1>::Zero();  ///< 0 where not given
  Eigen::Matrix<double, N, N> covariance;  ///< given block; p0 I where an element is not given
  std::array<bool, N> given{};             ///< present and finite

  [[nodiscard]] bool position_given() const noexcept { return given[static_cast<std::size_t>(kPosition)]; }
};

/// Axis `axis` of an import (RT-safe): the elements present and finite, the covariance block
/// between given elements (none with a null `covariance`), the block's initial values
/// (x = 0, P = p0 I) for the rest.
template <int N>
ImportedAxis<N> import_axis(std::size_t axis, std::size_t axes, const double* values, const double* covariance,
                            const std::uint8_t* present, double p0) noexcept {
  ImportedAxis<N> in;
  in.covariance = p0 * Eigen::Matrix<double, N, N>::Identity();
  const std::size_t n = axes * N;
  for (int a = 0; a < N; ++a) {
    const std::size_t k = axis * N + static_cast<std::size_t>(a);
    in.given[static_cast<std::size_t>(a)] = present[k] != 0 && std::isfinite(values[k]);
    if (in.given[static_cast<std::size_t>(a)]) in.state(a) = values[k];
  }
  if (covariance != nullptr) {
    for (int a = 0; a < N; ++a) {
      for (int b = 0; b < N; ++b) {
        if (!in.given[static_cast<std::size_t>(a)] || !in.given[static_cast<std::size_t>(b)]) continue;
        in.covariance(a, b) =
            covariance[(axis * N + static_cast<std::size_t>(a)) * n + axis * N + static_cast<std::size_t>(b)];
      }
    }
  }
  return in;
}

}  // namespace lode::plugins::estimator
