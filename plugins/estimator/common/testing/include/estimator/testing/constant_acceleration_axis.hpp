// A simulated axis for the per-axis linear filters' tests (estimator.kalman,
// estimator.hybrid_h2hinf), written out independently of the filters: the constant-
// acceleration model they assume, driven by white jerk and measured with white noise, and the
// normalised innovation squared (NIS) of a filter run on it.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include "lode/sdk/testing/harness.hpp"

namespace lode::estimator_testing {

/// x_{k+1} = Phi x_k + Upsilon w_k (Phi, Upsilon of Kawato 2005, eq. 4.39 at period t), w ~ N(0, q)
/// (jerk), measured as y_k = x_k(0) + v_k, v ~ N(0, r). Fixed seed.
class ConstantAccelerationAxis {
 public:
  ConstantAccelerationAxis(double period_s, double q, double r, std::uint64_t seed, double initial_position)
      : q_(q), r_(r), rng_(seed), x_(initial_position, 0.0, 0.0) {
    const double t = period_s;
    phi_ << 1.0, t, 0.5 * t * t, 0.0, 1.0, t, 0.0, 0.0, 1.0;
    upsilon_ << t * t * t / 6.0, 0.5 * t * t, t;
  }
  double measure() { return x_(0) + std::sqrt(r_) * normal_(rng_); }
  void advance() { x_ = (phi_ * x_ + upsilon_ * (std::sqrt(q_) * normal_(rng_))).eval(); }

 private:
  double q_, r_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Eigen::Matrix3d phi_;
  Eigen::Vector3d upsilon_;
  Eigen::Vector3d x_;
};

/// Runs the started block on `truth` (one simulated axis per element of `measurement`, the
/// block's measurement input) for warmup + steps cycles and returns the mean over the last
/// `steps` of sum_i nu_i^2 / S_ii from innovation(). With the filter's own noise model that sum
/// is chi-square with m = axes degrees of freedom, mean m (Bar-Shalom, Li & Kirubarajan 2001,
/// §5.4.2). A faulting step or a step without innovation fails the test and gives NaN.
inline double mean_nis(lode::testing::BlockHarness& h, std::span<double> measurement,
                       std::vector<ConstantAccelerationAxis>& truth, int warmup, int steps) {
  constexpr std::size_t kMaxAxes = 6;
  double sum = 0.0;
  int count = 0;
  for (int k = 0; k < warmup + steps; ++k) {
    for (std::size_t i = 0; i < truth.size(); ++i) measurement[i] = truth[i].measure();
    if (h.step() != StepStatus::ok) {
      ADD_FAILURE() << "step " << k << " faulted: " << h.block().fault_reason();
      return std::numeric_limits<double>::quiet_NaN();
    }
    double nu[kMaxAxes], s[kMaxAxes];
    if (!h.estimator().innovation(nu, s)) {
      ADD_FAILURE() << "no innovation after step " << k;
      return std::numeric_limits<double>::quiet_NaN();
    }
    if (k >= warmup) {
      for (std::size_t i = 0; i < truth.size(); ++i) sum += nu[i] * nu[i] / s[i];
      ++count;
    }
    for (auto& t : truth) t.advance();
  }
  return sum / count;
}

}  // namespace lode::estimator_testing
