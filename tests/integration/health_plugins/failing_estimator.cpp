// A stand-in for a pose estimator that goes wrong on cue, for the health monitor's tests
// (tests/integration/health_monitor_test.cpp). It passes the measured pose through
// (pose = measurement, velocity 0) and can fail in the two ways no shipped estimator can be
// made to fail on demand:
//
// - Its exported covariance turns indefinite from `indefinite_from_cycle` on, as the
//   covariance of a filter with the short-form update P+ = (I - K H) P- does once rounding
//   has pushed it off the positive-definite cone. The diagonal stays positive (a check of
//   the variances alone would pass); the position-velocity correlation of the first axis
//   exceeds 1, which only a factorisation sees. estimator.kalman (Joseph form, symmetrised)
//   and estimator.hybrid_h2hinf (a sum of positive semidefinite terms, unstable blends
//   refused) keep their covariance positive definite for every accepted parameter.
// - Its step() takes `slow_step_us` on the `slow_cycles` cycles from `slow_from_cycle` on,
//   as an iterative solver that runs to its iteration cap does.
//
// The innovation it reports is 0 with unit variance: it has no measurement model to be
// inconsistent with, so it never trips the innovation test itself.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>

#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/plugin.hpp"

namespace {

constexpr std::size_t kMaxAxes = 6;
constexpr std::size_t kStates = 3;  // position, velocity, acceleration per axis (as estimator.kalman)

class FailingEstimator final : public lode::Block, public lode::EstimatorState {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    lode::Params& params = ctx.params();
    indefinite_from_ = params.integer("indefinite_from_cycle", -1);
    slow_from_ = params.integer("slow_from_cycle", -1);
    slow_cycles_ = params.integer("slow_cycles", 1'000'000'000);
    slow_step_ns_ = static_cast<std::int64_t>(params.number("slow_step_us", 100.0) * 1e3);
    params.check(slow_cycles_ >= 0 && slow_step_ns_ >= 0, "slow_cycles", "slow_cycles and slow_step_us must be >= 0");
    ctx.declare_input(measurement_, "measurement", {}, true);
    const lode::Elements* source = ctx.input_source("measurement");
    if (source == nullptr || source->empty() || source->size() > kMaxAxes) {
      params.fail("inputs", "the measurement must come from a configured output of 1 to 6 elements");
      return lode::Status::error("invalid parameters");
    }
    elements_ = *source;
    lode::Elements velocity;
    for (const auto& e : elements_) velocity.push_back({e.name + "_dot", e.unit + "/s"});
    ctx.declare_output(pose_, "pose", elements_);
    ctx.declare_output(velocity_, "velocity", velocity);
    return params.ok() ? lode::Status::ok() : lode::Status::error("invalid parameters");
  }

  lode::StepStatus step(const lode::Tick& tick) noexcept override {
    const auto cycle = static_cast<std::int64_t>(tick.cycle);
    if (slow_from_ >= 0 && cycle >= slow_from_ && cycle - slow_from_ < slow_cycles_) {
      const auto until = std::chrono::steady_clock::now() + std::chrono::nanoseconds(slow_step_ns_);
      while (std::chrono::steady_clock::now() < until) {
      }
    }
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      pose_[i] = measurement_[i];
      velocity_[i] = 0.0;
    }
    indefinite_ = indefinite_from_ >= 0 && cycle >= indefinite_from_;
    stepped_ = true;
    return lode::StepStatus::ok;
  }

  [[nodiscard]] lode::StateLayout state_layout() const override {
    lode::StateLayout layout;
    layout.covariance = true;
    for (const auto& e : elements_) {
      layout.elements.push_back({e.name, e.unit});
      layout.elements.push_back({e.name + "_dot", e.unit + "/s"});
      layout.elements.push_back({e.name + "_ddot", e.unit + "/s^2"});
    }
    return layout;
  }

  void export_state(double* values, double* covariance) const noexcept override {
    const std::size_t n = kStates * elements_.size();
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      values[kStates * i] = pose_[i];
      values[kStates * i + 1] = 0.0;
      values[kStates * i + 2] = 0.0;
    }
    if (covariance == nullptr) return;
    std::fill(covariance, covariance + n * n, 0.0);
    for (std::size_t k = 0; k < n; ++k) covariance[k * n + k] = kVariance;
    // Correlation 1.5 between the first axis's position and velocity: indefinite.
    if (indefinite_) covariance[1] = covariance[n] = 1.5 * kVariance;
  }

  [[nodiscard]] std::size_t innovation_size() const override { return elements_.size(); }
  bool innovation(double* residual, double* variance) const noexcept override {
    if (!stepped_) return false;
    std::fill(residual, residual + elements_.size(), 0.0);
    std::fill(variance, variance + elements_.size(), 1.0);
    return true;
  }

 private:
  static constexpr double kVariance = 1e-10;
  std::int64_t indefinite_from_ = -1;
  std::int64_t slow_from_ = -1;
  std::int64_t slow_cycles_ = 0;
  std::int64_t slow_step_ns_ = 0;
  lode::Elements elements_;
  lode::InputPort measurement_;
  lode::OutputPort pose_;
  lode::OutputPort velocity_;
  bool indefinite_ = false;
  bool stepped_ = false;
};

constexpr lode::ParamDoc kParams[] = {
    {"indefinite_from_cycle", "integer", "-1", "the exported covariance is indefinite from this cycle on (-1 = never)"},
    {"slow_from_cycle", "integer", "-1", "step() takes slow_step_us from this cycle on (-1 = never)"},
    {"slow_cycles", "integer", "1e9", "how many cycles are slow"},
    {"slow_step_us", "number", "100", "duration of a slow step() [us]"},
};
constexpr lode::PortSpec kPorts[] = {
    {"measurement", lode::PortDirection::in, "a measured pose, e.g. glsdc.pose"},
    {"pose", lode::PortDirection::out, "the measurement, passed through"},
    {"velocity", lode::PortDirection::out, "0 per axis"},
};

}  // namespace

LODE_PLUGIN(FailingEstimator, "test.failing_estimator", lode::PluginKind::block, "0.0.1",
            "Test plugin: a pass-through pose estimator whose covariance turns indefinite or whose step "
            "turns slow at given cycles",
            kParams, kPorts)
