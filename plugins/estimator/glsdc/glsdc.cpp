#include "glsdc.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "estimator/describe_json.hpp"
#include "estimator/weighted_least_squares.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/rt_log.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace {

constexpr std::int64_t kMaxIterations = 100;

}  // namespace

Status Glsdc::configure(ConfigureContext& ctx) {
  block_name_ = ctx.block_name();
  Params& params = ctx.params();
  model_name_ = params.text("model");
  mode_ = params.choice("mode", {"3dof", "2dof"}, "3dof") == "2dof" ? Mode::two_dof
                                                                    : Mode::three_dof;
  free_states_ = (mode_ == Mode::two_dof) ? 2 : kStates;
  invalid_measurement_ = params.choice("invalid_measurement", {"fault", "propagate"}, "fault") == "propagate"
                             ? InvalidMeasurement::propagate
                             : InvalidMeasurement::fault;
  compile_time_sizes_ = params.flag("compile_time_sizes", true);
  iterations_ = params.integer("iterations", 1);
  backoff_ = params.number("backoff", 0.2);
  noise_std_v_ = params.numbers("noise_std_v", std::vector<double>{1e-3});
  const std::vector<double> initial = params.numbers("initial", {0.0, 0.0, 0.0}, 3);
  initial_ = State(initial.at(0), initial.at(1), initial.at(2));

  params.check(iterations_ >= 1 && iterations_ <= kMaxIterations, "iterations",
               "must be 1.." + std::to_string(kMaxIterations) + " Gauss-Newton steps per tick, got " +
                   std::to_string(iterations_));
  params.check(backoff_ > 0.0 && backoff_ <= 1.0, "backoff",
               "must be in (0, 1]: the fraction of the step kept when the cost rises (thesis 0.2), "
               "got " + number_text(backoff_));

  model_ = ctx.measurement_model("model");
  if (!model_) return Status::error("invalid parameters");  // the context said why

  const Elements& states = model_->state_elements();
  const bool planar_state = states.size() == 3 && states[0].unit == "m" && states[1].unit == "m" &&
                            states[2].unit == "rad";
  params.check(planar_state, "model",
               "model '" + model_name_ + "' must depend on [x: m, y: m, theta_z: rad], it has " +
                   std::to_string(states.size()) + " state elements");
  const Elements& channels = model_->channels();
  channels_ = static_cast<int>(channels.size());
  if (channels_ > kMaxChannels || channels_ < free_states_) {
    params.fail("model", "model '" + model_name_ + "' has " + std::to_string(channels_) +
                             " channels; " + (mode_ == Mode::two_dof ? "2dof" : "3dof") +
                             " needs " + std::to_string(free_states_) + " to " +
                             std::to_string(kMaxChannels));
  }
  estimator::check_channel_noise(params, noise_std_v_, channels_);
  if (!params.ok()) return Status::error("invalid parameters");

  // W = diag(1/sigma^2) (the thesis uses sigma = 1 mV on every channel).
  weight_.resize(channels_);
  estimator::set_channel_weights(noise_std_v_, channels_, weight_);
  measured_.setZero(channels_);
  predicted_.setZero(channels_);
  trial_.setZero(channels_);
  jacobian_.setZero(channels_, kStates);
  sized_ = compile_time_sizes_ && mode_ == Mode::three_dof && channels_ == kSizedChannels;
  if (sized_) estimator::set_channel_weights(noise_std_v_, channels_, sized_work_.weight);

  ctx.declare_input(measurement_, "measurement", channels);
  if (mode_ == Mode::two_dof) ctx.declare_input(theta_, "theta", {{"theta_z", "rad"}}, false);
  ctx.declare_output(pose_, "pose", {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}});
  ctx.declare_output(covariance_, "covariance",
                     {{"xx", "m^2"}, {"xy", "m^2"}, {"xth", "m*rad"},
                      {"yx", "m^2"}, {"yy", "m^2"}, {"yth", "m*rad"},
                      {"thx", "m*rad"}, {"thy", "m*rad"}, {"thth", "rad^2"}});
  ctx.declare_output(cost_, "cost", {{"cost", "1"}});
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status Glsdc::activate() {
  z_ = initial_;
  r_.setZero();
  has_covariance_ = false;
  cost_value_ = 0.0;
  linearisation_valid_ = false;
  singular_skips_ = 0;
  backoffs_ = 0;
  publish();
  return Status::ok();
}

void Glsdc::linearise(const State& z) noexcept {
  if (linearisation_valid_ && z == linearised_at_) return;
  model_->jacobian(z.data(), predicted_.data(), jacobian_.data());
  linearised_at_ = z;
  linearisation_valid_ = true;
}

double Glsdc::cost_of(const ChannelVector& f) const noexcept {
  return estimator::weighted_cost(measured_, f, weight_, static_cast<std::size_t>(channels_));
}

bool Glsdc::solve(Covariance& r, State& dz) const noexcept {
  // Normal equations over the free states: N = H'WH, g = H'W(y - f) (eq. 4.27-4.28).
  Covariance normal = Covariance::Zero();
  State gradient = State::Zero();
  for (int i = 0; i < channels_; ++i) {
    const double w = weight_(i);
    const double residual = measured_(i) - predicted_(i);
    for (int a = 0; a < free_states_; ++a) {
      gradient(a) += jacobian_(i, a) * w * residual;
      for (int b = 0; b < free_states_; ++b) normal(a, b) += jacobian_(i, a) * w * jacobian_(i, b);
    }
  }
  // 2dof: theta is not estimated. A decoupled pivot of the size of the free diagonal keeps one
  // 3x3 code path without changing the conditioning; its row and column are zeroed below.
  if (free_states_ < kStates) {
    double mean_diagonal = 0.0;
    for (int a = 0; a < free_states_; ++a) mean_diagonal += normal(a, a) / free_states_;
    for (int a = free_states_; a < kStates; ++a) normal(a, a) = mean_diagonal;
  }
  // Not Jacobi-scaled on purpose: a column that is zero up to rounding (every slope at a field
  // extremum) must read as singular, not be scaled back to 1. The columns differ only by the
  // sensor lever arm (V/m vs V/rad, ~0.1 m), far from the 1e-12 threshold.
  const Eigen::LDLT<Covariance> ldlt(normal);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || !(ldlt.rcond() >= kMinRcond))
    return false;
  r = ldlt.solve(Covariance::Identity());
  for (int a = free_states_; a < kStates; ++a) {
    r.row(a).setZero();
    r.col(a).setZero();
  }
  dz = r * gradient;  // Gauss-Newton step R H'W dy
  return r.allFinite() && dz.allFinite();
}

bool Glsdc::iterate() noexcept {
  for (std::int64_t it = 0; it < iterations_; ++it) {
    linearise(z_);
    const double cost_before = cost_of(predicted_);
    Covariance r;
    State dz;
    if (!solve(r, dz)) return true;  // singular: hold the estimate (skip the update)
    const State z_full = z_ + dz;
    model_->evaluate(z_full.data(), trial_.data());
    const double cost_after = cost_of(trial_);
    if (cost_after > cost_before) {
      // Thesis Appendix B/C: z <- z + dz - (1 - backoff) dz, no re-check.
      z_ += backoff_ * dz;
      ++backoffs_;
    } else {
      z_ = z_full;
    }
  }
  return false;
}

bool Glsdc::finish(Covariance& r) noexcept {
  linearise(z_);
  cost_value_ = cost_of(predicted_);
  if (!std::isfinite(cost_value_)) return false;
  State dz;
  return solve(r, dz);
}

StepStatus Glsdc::step(const Tick& /*tick*/) noexcept {
  // Inputs are checked before anything changes: with invalid_measurement: propagate a bad
  // cycle publishes NaN and leaves the estimate (the next warm start) as it was.
  const bool propagate = invalid_measurement_ == InvalidMeasurement::propagate;
  for (int i = 0; i < channels_; ++i) {
    if (!std::isfinite(measurement_[static_cast<std::size_t>(i)])) {
      if (!propagate) return fault("non-finite measurement");
      publish_invalid();
      return StepStatus::ok;
    }
  }
  double theta = 0.0;
  if (mode_ == Mode::two_dof) {
    theta = theta_.connected() ? theta_[0] : initial_(kThetaZ);
    if (!std::isfinite(theta)) {
      if (!propagate) return fault("non-finite theta input");
      publish_invalid();
      return StepStatus::ok;
    }
  }
  if (sized_) {
    for (int i = 0; i < kSizedChannels; ++i) sized_work_.measured(i) = measurement_[static_cast<std::size_t>(i)];
  } else {
    for (int i = 0; i < channels_; ++i) measured_(i) = measurement_[static_cast<std::size_t>(i)];
  }
  if (mode_ == Mode::two_dof) z_(kThetaZ) = theta;

  const State z_before = z_;
  bool singular = sized_ ? iterate_sized() : iterate();
  if (!z_.allFinite()) {
    z_ = z_before;
    linearisation_valid_ = false;
    return fault("non-finite estimate");
  }

  // Covariance and cost of the published estimate (eq. 4.28 at the final iterate). The
  // linearisation is kept for the next tick's first step.
  Covariance r;
  const bool solved = sized_ ? finish_sized(r) : finish(r);
  if (!std::isfinite(cost_value_)) return fault("non-finite cost");
  if (solved) {
    r_ = r;
    has_covariance_ = true;
  } else {
    singular = true;  // keep the last good covariance
  }
  if (singular) {
    // Report the first skip of a run of them, not every tick: the ring is shared.
    if (!was_singular_)
      lode::rt_log(lode::LogLevel::warn, block_name_.c_str(),
                   "H^T W H singular (rcond < {}): holding the estimate", kMinRcond);
    ++singular_skips_;
  }
  was_singular_ = singular;
  publish();
  return StepStatus::ok;
}

void Glsdc::publish() noexcept {
  for (int a = 0; a < kStates; ++a) {
    pose_[static_cast<std::size_t>(a)] = z_(a);
    for (int b = 0; b < kStates; ++b) covariance_[static_cast<std::size_t>(a * kStates + b)] = r_(a, b);
  }
  cost_[0] = cost_value_;
}

void Glsdc::publish_invalid() noexcept {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t a = 0; a < static_cast<std::size_t>(kStates); ++a) pose_[a] = nan;
  for (std::size_t k = 0; k < static_cast<std::size_t>(kStates * kStates); ++k) covariance_[k] = nan;
  cost_[0] = nan;
}

StateLayout Glsdc::state_layout() const {
  StateLayout layout;
  layout.elements = {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};
  layout.covariance = true;
  return layout;
}

void Glsdc::export_state(double* values, double* covariance) const noexcept {
  for (int a = 0; a < kStates; ++a) values[a] = z_(a);
  if (covariance == nullptr) return;
  for (int a = 0; a < kStates; ++a) {
    for (int b = 0; b < kStates; ++b) {
      const bool estimated = has_covariance_ && a < free_states_ && b < free_states_;
      // Symmetrised: the LDLT solve leaves R asymmetric by an ulp or so (see the header).
      covariance[a * kStates + b] = estimated ? 0.5 * (r_(a, b) + r_(b, a)) : (a == b ? kUnknownVariance : 0.0);
    }
  }
}

void Glsdc::import_state(const double* values, const double* /*covariance*/, const std::uint8_t* present) noexcept {
  // The warm start only: R is recomputed from the next measurement (eq. 4.28).
  for (int a = 0; a < kStates; ++a) {
    z_(a) = (present[a] != 0 && std::isfinite(values[a])) ? values[a] : initial_(a);
  }
  linearisation_valid_ = false;
}

void Glsdc::describe(Json& out) const {
  out["model"] = model_name_;
  out["mode"] = mode_ == Mode::two_dof ? "2dof" : "3dof";
  out["invalid_measurement"] = invalid_measurement_ == InvalidMeasurement::propagate
                                   ? "propagate (NaN pose/covariance/cost for the cycle, estimate kept)"
                                   : "fault";
  out["iterations"] = iterations_;
  out["algebra"] = sized_ ? "sized at compile time (3dof, 4 channels)" : "generic (sizes chosen at configure)";
  out["backoff"] = backoff_;
  std::vector<double> sigma(static_cast<std::size_t>(channels_));
  std::vector<double> w(static_cast<std::size_t>(channels_));
  for (int i = 0; i < channels_; ++i) {
    sigma[static_cast<std::size_t>(i)] = 1.0 / std::sqrt(weight_(i));
    w[static_cast<std::size_t>(i)] = weight_(i);
  }
  out["noise_std_v"] = sigma;
  out["weight_diagonal_1_per_v2"] = w;
  out["initial"] = std::vector<double>{initial_(0), initial_(1), initial_(2)};
  out["min_rcond"] = kMinRcond;
  if (model_) out["model_description"] = estimator::description_of(*model_);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"model", "text", nullptr,
     "name of a measurement model in `models:` with state [x: m, y: m, theta_z: rad]"},
    {"mode", "text", "3dof",
     "3dof: estimate x, y, theta_z; 2dof: theta fixed (theta input or initial[2]), eq. 4.29-4.30"},
    {"iterations", "integer", "1", "Gauss-Newton steps per tick (1..100), warm-started"},
    {"compile_time_sizes", "bool", "true",
     "true: 3dof over 4 channels runs algebra sized at compile time (same results); false: the generic code"},
    {"backoff", "number", "0.2",
     "fraction of the step kept when the cost rises (thesis scaling factor), in (0, 1]"},
    {"noise_std_v", "number | list<number>", "1e-3",
     "channel noise std [V], one value or one per channel: W = diag(1/sigma^2)"},
    {"initial", "list<number>[3]", "[0, 0, 0]", "start estimate x [m], y [m], theta_z [rad]"},
    {"invalid_measurement", "text", "fault",
     "fault: a non-finite channel (or theta input) faults the step; propagate: that cycle's pose, covariance "
     "and cost outputs are NaN, the warm-start pose is kept for the next cycle and the step succeeds"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "the model's channels [V], e.g. a1, b1, c1, d2"},
    {"theta", PortDirection::in, "optional: theta_z [rad] (e.g. from a laser)", "with mode: 2dof"},
    {"pose", PortDirection::out, "x [m], y [m], theta_z [rad]"},
    {"covariance", PortDirection::out,
     "R = (H'WH)^-1 row-major (xx, xy, xth, yx, yy, yth, thx, thy, thth) [m^2, m*rad, rad^2]"},
    {"cost", PortDirection::out, "weighted cost J = (y - h(z))' W (y - h(z)) at the published estimate [1]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::Glsdc, "estimator.glsdc", lode::PluginKind::estimator, "0.1.0",
            "Gauss-Newton (GLSDC) planar pose from Hall voltages (Kawato §4.3, eq. 4.27-4.30)",
            lode::plugins::kParams, lode::plugins::kPorts)
