// Weighted least squares over measurement channels, as the pose solvers (estimator.glsdc,
// estimator.gap_pose, estimator.least_squares) fit a model's h(z) to the channel voltages y:
//   J = |y - h(z)|^2_W = sum_i w_i (y_i - h_i(z))^2,   W = diag(1 / sigma_i^2).
#pragma once

#include <cstddef>
#include <vector>

#include "lode/sdk/params.hpp"

namespace lode::plugins::estimator {

/// Checks `noise_std_v` (configure()): one std [V] for every channel or one per channel,
/// every one > 0. Problems are reported on "noise_std_v".
void check_channel_noise(Params& params, const std::vector<double>& noise_std_v, int channels);

/// weight(i) = 1 / sigma_i^2 [1/V^2] for every channel, from a checked noise_std_v.
template <typename Weights>
void set_channel_weights(const std::vector<double>& noise_std_v, int channels, Weights& weight) {
  for (int i = 0; i < channels; ++i) {
    const double sigma = noise_std_v.size() == 1 ? noise_std_v[0] : noise_std_v[static_cast<std::size_t>(i)];
    weight(i) = 1.0 / (sigma * sigma);
  }
}

/// J = sum_i w_i (y_i - f_i)^2 over the first `channels` channels (RT-safe).
template <typename Measured, typename Predicted, typename Weights>
double weighted_cost(const Measured& y, const Predicted& f, const Weights& w, std::size_t channels) noexcept {
  double cost = 0.0;
  for (std::size_t i = 0; i < channels; ++i) {
    const double residual = y[i] - f[i];
    cost += w[i] * residual * residual;
  }
  return cost;
}

}  // namespace lode::plugins::estimator
