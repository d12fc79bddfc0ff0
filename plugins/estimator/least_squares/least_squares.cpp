#include "least_squares.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "estimator/describe_json.hpp"
#include "estimator/weighted_least_squares.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace {

/// Smallest ratio of the Cholesky factor's diagonal entries squared (min / max) that still
/// counts as a regular normal matrix: below it a direction of the pose is not observed.
constexpr double kMinPivotRatio = 1e-14;

}  // namespace

Status LeastSquaresPose::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  iterations_ = static_cast<int>(params.integer("iterations", 1));
  std::vector<double> noise = params.numbers("noise_std_v", std::vector<double>{1e-3});
  const std::vector<double> initial = params.numbers("initial", std::vector<double>{});
  params.check(iterations_ >= 1 && iterations_ <= 20, "iterations",
               "Gauss-Newton steps per tick must be 1 ... 20, got " + std::to_string(iterations_));

  std::vector<std::unique_ptr<MeasurementModel>> models = ctx.measurement_models("models");
  const std::vector<std::string> names = params.texts("models", {});
  slots_.clear();
  state_elements_.clear();
  channel_elements_.clear();
  for (std::size_t m = 0; m < models.size(); ++m) {
    Slot slot;
    slot.name = models.size() == names.size() ? names[m] : "model " + std::to_string(m);
    slot.model = std::move(models[m]);
    for (const Element& e : slot.model->state_elements()) {
      const auto found = std::find_if(state_elements_.begin(), state_elements_.end(),
                                      [&](const Element& s) { return s.name == e.name; });
      if (found == state_elements_.end()) {
        slot.state_index.push_back(state_elements_.size());
        state_elements_.push_back(e);
      } else {
        if (canonical_unit(found->unit) != canonical_unit(e.unit)) {
          params.fail("models", "model '" + slot.name + "' has state '" + e.name + "' in '" + e.unit +
                                    "', another model has it in '" + found->unit + "'");
        }
        slot.state_index.push_back(static_cast<std::size_t>(found - state_elements_.begin()));
      }
    }
    slot.first_channel = channel_elements_.size();
    slot.channel_count = slot.model->channels().size();
    for (const Element& e : slot.model->channels()) channel_elements_.push_back(e);
    slots_.push_back(std::move(slot));
  }
  states_ = state_elements_.size();
  channels_ = channel_elements_.size();
  if (!models.empty() || params.ok()) {
    if (states_ == 0 || states_ > static_cast<std::size_t>(kMaxStates)) {
      params.fail("models", "the models' states number " + std::to_string(states_) + "; 1 ... " +
                                std::to_string(kMaxStates) + " are supported");
    }
    if (channels_ < states_ || channels_ > static_cast<std::size_t>(kMaxChannels)) {
      params.fail("models", "the models have " + std::to_string(channels_) + " channels for " +
                                std::to_string(states_) + " states: need at least one channel per state and at most " +
                                std::to_string(kMaxChannels));
    }
  }

  if (noise.size() == 1 && channels_ > 1) noise.assign(channels_, noise.front());
  if (noise.size() != channels_ && channels_ > 0) {
    params.fail("noise_std_v", "expected one number or " + std::to_string(channels_) + " (one per channel), got " +
                                   std::to_string(noise.size()));
  }
  weight_.clear();
  for (double sigma : noise) {
    if (!(sigma > 0.0)) params.fail("noise_std_v", "channel noise std must be > 0 V, got " + number_text(sigma));
    weight_.push_back(sigma > 0.0 ? 1.0 / (sigma * sigma) : 0.0);
  }
  initial_ = initial.empty() ? std::vector<double>(states_, 0.0) : initial;
  if (initial_.size() != states_) {
    params.fail("initial", "expected " + std::to_string(states_) + " numbers (one per state: " +
                               [&] {
                                 std::string s;
                                 for (const Element& e : state_elements_) s += (s.empty() ? "" : ", ") + e.name;
                                 return s;
                               }() +
                               "), got " + std::to_string(initial_.size()));
  }

  ctx.declare_input(measurement_, "measurement", {}, true);
  const Elements* source = ctx.input_source("measurement");
  if (source != nullptr && params.ok()) {
    if (source->size() != channels_) {
      params.fail("inputs", "the measurement has " + std::to_string(source->size()) + " elements, the models have " +
                                std::to_string(channels_) + " channels");
    } else {
      for (std::size_t i = 0; i < channels_; ++i) {
        if ((*source)[i].name != channel_elements_[i].name ||
            !units_compatible((*source)[i].unit, channel_elements_[i].unit)) {
          params.fail("inputs", "measurement element " + std::to_string(i) + " is '" + (*source)[i].name + "' [" +
                                    (*source)[i].unit + "], the models expect '" + channel_elements_[i].name + "' [" +
                                    channel_elements_[i].unit + "] (channels in `models` order)");
          break;
        }
      }
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");

  const auto n = static_cast<Eigen::Index>(states_);
  estimate_.resize(n);
  normal_.resize(n, n);
  gradient_.resize(n);
  ctx.declare_output(pose_, "pose", state_elements_);
  ctx.declare_output(cost_, "cost", {{"cost", "1"}});
  return Status::ok();
}

Status LeastSquaresPose::activate() {
  for (std::size_t i = 0; i < states_; ++i) {
    estimate_(static_cast<Eigen::Index>(i)) = initial_[i];
    pose_[i] = initial_[i];
  }
  cost_[0] = 0.0;
  return Status::ok();
}

void LeastSquaresPose::linearize(bool with_jacobian) noexcept {
  if (with_jacobian) std::fill_n(jacobian_.begin(), channels_ * states_, 0.0);
  for (const Slot& slot : slots_) {
    const std::size_t model_states = slot.state_index.size();
    for (std::size_t j = 0; j < model_states; ++j) {
      model_state_[j] = estimate_(static_cast<Eigen::Index>(slot.state_index[j]));
    }
    double* y = predicted_.data() + slot.first_channel;
    if (!with_jacobian) {
      slot.model->evaluate(model_state_.data(), y);
      continue;
    }
    slot.model->jacobian(model_state_.data(), y, model_jacobian_.data());
    for (std::size_t c = 0; c < slot.channel_count; ++c) {
      for (std::size_t j = 0; j < model_states; ++j) {
        jacobian_[(slot.first_channel + c) * states_ + slot.state_index[j]] += model_jacobian_[c * model_states + j];
      }
    }
  }
}

StepStatus LeastSquaresPose::step(const Tick& /*tick*/) noexcept {
  for (std::size_t c = 0; c < channels_; ++c) {
    if (!std::isfinite(measurement_[c])) return fault("non-finite measurement");
  }
  const auto n = static_cast<Eigen::Index>(states_);
  for (int iteration = 0; iteration < iterations_; ++iteration) {
    linearize(true);
    // Normal equations H'WH dz = H'W (y - f).
    normal_.setZero();
    gradient_.setZero();
    for (std::size_t c = 0; c < channels_; ++c) {
      const double w = weight_[c];
      const double residual = measurement_[c] - predicted_[c];
      const double* row = jacobian_.data() + c * states_;
      for (Eigen::Index i = 0; i < n; ++i) {
        const double wi = w * row[i];
        if (wi == 0.0) continue;
        gradient_(i) += wi * residual;
        for (Eigen::Index j = 0; j <= i; ++j) normal_(i, j) += wi * row[j];
      }
    }
    factor_.compute(normal_);  // reads the lower triangle
    if (factor_.info() != Eigen::Success) return fault("normal matrix H'WH is not positive definite");
    const auto diagonal = factor_.matrixLLT().diagonal();
    const double smallest = diagonal.minCoeff();
    const double largest = diagonal.maxCoeff();
    if (!(smallest * smallest > kMinPivotRatio * largest * largest)) {
      return fault("normal matrix H'WH is singular: a pose direction is not observed");
    }
    factor_.solveInPlace(gradient_);
    if (!gradient_.allFinite()) return fault("Gauss-Newton step is not finite");
    estimate_ += gradient_;
  }
  linearize(false);
  const double cost = estimator::weighted_cost(measurement_, predicted_, weight_, channels_);
  if (!std::isfinite(cost)) return fault("cost is not finite");
  for (std::size_t i = 0; i < states_; ++i) pose_[i] = estimate_(static_cast<Eigen::Index>(i));
  cost_[0] = cost;
  return StepStatus::ok;
}

void LeastSquaresPose::describe(Json& out) const {
  Json models = Json::array();
  for (const Slot& slot : slots_) {
    Json m = Json::object();
    m["name"] = slot.name;
    m["first_channel"] = static_cast<int>(slot.first_channel);
    m["channels"] = static_cast<int>(slot.channel_count);
    Json states = Json::array();
    for (std::size_t j : slot.state_index) states.push(state_elements_[j].name);
    m["states"] = std::move(states);
    m["model"] = estimator::description_of(*slot.model);
    models.push(std::move(m));
  }
  out["models"] = std::move(models);
  Json states = Json::array();
  for (const Element& e : state_elements_) states.push(e.name + " [" + e.unit + "]");
  out["state"] = std::move(states);
  out["iterations_per_tick"] = iterations_;
  std::vector<double> sigma;
  for (double w : weight_) sigma.push_back(1.0 / std::sqrt(w));
  out["noise_std_v"] = sigma;
  out["initial"] = initial_;
  out["update"] = "dz = (H'WH)^-1 H'W (y - h(z)), W = diag(1/noise_std_v^2), warm-started each tick";
}

namespace {

constexpr ParamDoc kParams[] = {
    {"models", "text|list<text>", nullptr,
     "measurement models in `models:` (e.g. [hall, laser]); their channels are concatenated in this order"},
    {"noise_std_v", "number|list<number>", "1e-3", "channel noise std [V] per channel or one for all: W = diag(1/sigma^2)"},
    {"iterations", "integer", "1", "Gauss-Newton steps per tick, 1 ... 20"},
    {"initial", "list<number>", "zeros", "the pose after activate(), one number per state (union order)"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "every model's channels, in `models` order [V]"},
    {"pose", PortDirection::out, "union of the models' state elements, in first-appearance order"},
    {"cost", PortDirection::out, "weighted residual |y - h(z)|^2_W at the published pose [1]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::LeastSquaresPose, "estimator.least_squares", lode::PluginKind::estimator, "0.1.0",
            "Pose from one or more measurement models by weighted Gauss-Newton (warm-started, n iterations per tick)",
            lode::plugins::kParams, lode::plugins::kPorts)
