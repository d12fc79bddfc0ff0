#include "gap_pose.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <string>
#include <vector>

#include "estimator/describe_json.hpp"
#include "estimator/weighted_least_squares.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace {

constexpr std::int64_t kMaxIterations = 20;
/// Reciprocal condition of H'WH after scaling every column to unit diagonal (the columns mix
/// V/m and V/rad, a lever arm apart); 0 when a degree of freedom is invisible to every probe.
double scaled_rcond(const GapPose::Normal& normal) {
  const GapPose::Pose diagonal = normal.diagonal();
  if (!(diagonal.minCoeff() > 0.0)) return 0.0;
  const GapPose::Pose scale = diagonal.cwiseSqrt().cwiseInverse();
  const GapPose::Normal scaled = scale.asDiagonal() * normal * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<GapPose::Normal> solver(scaled, Eigen::EigenvaluesOnly);
  return solver.eigenvalues().minCoeff() / solver.eigenvalues().maxCoeff();
}

constexpr const char* kPoseUnits[GapPose::kStates] = {"m", "m", "m", "rad", "rad", "rad"};

}  // namespace

Status GapPose::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  model_name_ = params.text("model");
  const std::int64_t iterations = params.integer("iterations", 2);
  noise_std_v_ = params.numbers("noise_std_v", std::vector<double>{1e-3});
  const std::vector<double> initial = params.numbers("initial", std::vector<double>(kStates, 0.0), kStates);
  for (int i = 0; i < kStates && i < static_cast<int>(initial.size()); ++i) initial_(i) = initial[static_cast<std::size_t>(i)];

  if (iterations < 1 || iterations > kMaxIterations) {
    params.fail("iterations", "must be 1 ... " + std::to_string(kMaxIterations) +
                                  " Gauss-Newton steps per tick, got " + std::to_string(iterations));
  } else {
    iterations_ = static_cast<int>(iterations);
  }

  Elements pose_elements{{"x", "m"}, {"y", "m"}, {"z", "m"}, {"phi", "rad"}, {"theta", "rad"}, {"psi", "rad"}};
  Elements channels;
  if (!model_name_.empty()) model_ = ctx.measurement_model("model");
  if (model_) {
    const Elements& states = model_->state_elements();
    bool pose = states.size() == static_cast<std::size_t>(kStates);
    for (std::size_t i = 0; pose && i < states.size(); ++i) pose = units_compatible(states[i].unit, kPoseUnits[i]);
    if (!pose) {
      params.fail("model", "model '" + model_name_ +
                               "' must depend on the pose [x, y, z: m, phi, theta, psi: rad], it has " +
                               std::to_string(states.size()) + " state elements");
    } else {
      pose_elements = states;
    }
    channels = model_->channels();
    channels_ = static_cast<int>(channels.size());
    if (channels_ < kStates || channels_ > kMaxChannels) {
      params.fail("model", "model '" + model_name_ + "' has " + std::to_string(channels_) +
                               " channels; the 6-DOF pose needs 6 to " + std::to_string(kMaxChannels));
    }
  }
  estimator::check_channel_noise(params, noise_std_v_, channels_);

  ctx.declare_input(measurement_, "measurement", channels, true);
  ctx.declare_output(pose_, "pose", pose_elements);
  ctx.declare_output(cost_, "cost", {{"cost", std::string(kDimensionless)}});
  if (!params.ok()) return Status::error("invalid parameters");
  if (!model_) return Status::error("measurement model '" + model_name_ + "' is not available (see above)");

  weight_.resize(channels_);
  measured_.resize(channels_);
  predicted_.resize(channels_);
  jacobian_.resize(channels_, kStates);
  estimator::set_channel_weights(noise_std_v_, channels_, weight_);
  // The probes must resolve all six degrees of freedom where the stage starts.
  model_->jacobian(initial_.data(), predicted_.data(), jacobian_.data());
  Normal normal = Normal::Zero();
  for (int i = 0; i < channels_; ++i) normal += jacobian_.row(i).transpose() * (weight_(i) * jacobian_.row(i));
  const double rcond = scaled_rcond(normal);
  if (!(rcond >= kMinRcond)) {
    params.fail("model", "the probes of model '" + model_name_ +
                             "' cannot resolve all six degrees of freedom at the initial pose (H'WH singular, "
                             "scaled rcond " + number_text(rcond) + ")");
    return Status::error("invalid parameters");
  }
  return Status::ok();
}

Status GapPose::activate() {
  pose_estimate_ = initial_;
  for (int i = 0; i < kStates; ++i) pose_[static_cast<std::size_t>(i)] = pose_estimate_(i);
  cost_[0] = 0.0;
  return Status::ok();
}

StepStatus GapPose::step(const Tick& /*tick*/) noexcept {
  for (int i = 0; i < channels_; ++i) {
    measured_(i) = measurement_[static_cast<std::size_t>(i)];
    if (!std::isfinite(measured_(i))) return fault("non-finite gap measurement");
  }
  Pose estimate = pose_estimate_;
  for (int iteration = 0; iteration < iterations_; ++iteration) {
    model_->jacobian(estimate.data(), predicted_.data(), jacobian_.data());
    Normal normal = Normal::Zero();
    Pose gradient = Pose::Zero();
    for (int i = 0; i < channels_; ++i) {
      const double w = weight_(i);
      const double residual = measured_(i) - predicted_(i);
      gradient += jacobian_.row(i).transpose() * (w * residual);
      normal += jacobian_.row(i).transpose() * (w * jacobian_.row(i));
    }
    const Eigen::LDLT<Normal> ldlt(normal);
    // A zero (or negative) pivot: some degree of freedom left the probes' view.
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > kMinPivot * ldlt.vectorD().maxCoeff())) {
      return fault("probe geometry singular at this pose (H'WH rank-deficient)");
    }
    const Pose step = ldlt.solve(gradient);
    if (!step.allFinite()) return fault("Gauss-Newton step not finite");
    estimate += step;
  }
  // The cost at the published pose (one more evaluation; h is cheap).
  model_->evaluate(estimate.data(), predicted_.data());
  const double cost = estimator::weighted_cost(measured_, predicted_, weight_, static_cast<std::size_t>(channels_));
  pose_estimate_ = estimate;
  for (int i = 0; i < kStates; ++i) pose_[static_cast<std::size_t>(i)] = estimate(i);
  cost_[0] = cost;
  return StepStatus::ok;
}

void GapPose::describe(Json& out) const {
  out["model"] = model_name_;
  out["iterations"] = iterations_;
  out["noise_std_v"] = noise_std_v_;
  out["initial"] = std::vector<double>(initial_.data(), initial_.data() + kStates);
  out["method"] = "weighted Gauss-Newton, warm start from the previous tick: dP = (H'WH)^-1 H'W (y - h(P))";
  if (model_) {
    // The pose covariance for white channel noise at home, (H'WH)^-1: the pose noise the probe
    // geometry turns the channel noise into (translations in m, angles in rad).
    const Pose home = Pose::Zero();
    ChannelVector y(channels_);
    ChannelJacobian h(channels_, kStates);
    model_->jacobian(home.data(), y.data(), h.data());
    Normal normal = Normal::Zero();
    for (int i = 0; i < channels_; ++i) normal += h.row(i).transpose() * (weight_(i) * h.row(i));
    const Normal covariance = normal.inverse();
    std::vector<double> std_dev;
    for (int i = 0; i < kStates; ++i) std_dev.push_back(std::sqrt(covariance(i, i)));
    out["pose_noise_std_at_home"] = std_dev;
    out["model_description"] = estimator::description_of(*model_);
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"model", "text", nullptr,
     "name of a measurement model in `models:` with state [x, y, z: m, phi, theta, psi: rad], 6 ... 16 channels "
     "(e.g. sensor.capacitive_gap)"},
    {"iterations", "integer", "2", "Gauss-Newton steps per tick, 1 ... 20"},
    {"noise_std_v", "number|list<number>", "1e-3", "channel noise std [V] for the weights W = diag(1/sigma^2), > 0"},
    {"initial", "list<number>[6]", "[0, 0, 0, 0, 0, 0]", "pose the first tick starts from [m, rad]"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "the model's channels [V], in order (e.g. board.signals)"},
    {"pose", PortDirection::out, "x, y, z [m], phi, theta, psi [rad]"},
    {"cost", PortDirection::out, "weighted squared residual |y - h(P)|_W^2 [1]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::GapPose, "estimator.gap_pose", lode::PluginKind::estimator, "0.1.0",
            "6-DOF pose from gap-probe voltages by Gauss-Newton through a measurement model (Gutierrez & Li "
            "2024 forward kinematics)",
            lode::plugins::kParams, lode::plugins::kPorts)
