#include "estimator/model_estimator.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

#include "estimator/element_names.hpp"
#include "estimator/model_configuration.hpp"
#include "estimator/usable_covariance.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins::nonlinear {

using estimator::element_list;

Status ModelEstimator::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  dt_ = ctx.period_s();
  process_name_ = params.text("process");
  measurement_name_ = params.text("measurement");
  process_ = ctx.process_model("process");
  measurement_ = ctx.measurement_model("measurement");
  const std::vector<double> q = params.numbers("q");
  const std::vector<double> r = params.numbers("r");
  const std::string basis = params.choice("process_noise", {"per_step", "per_second"}, std::string_view("per_step"));
  noise_basis_ = basis == "per_second" ? NoiseBasis::per_second : NoiseBasis::per_step;
  const std::vector<double> x0 = params.numbers("initial_state");
  const std::vector<double> p0 = params.numbers("p0");
  read_filter_params(params);

  ctx.declare_input(measurement_in_, "measurement", {}, true);
  if (!process_ || !measurement_) {
    // The context has said why; declare the optional input so the wiring is still checked.
    ctx.declare_input(input_in_, "input", {}, false);
    return Status::error("invalid parameters");
  }

  const Elements& states = process_->process_state();
  const Elements& inputs = process_->process_inputs();
  const Elements& channels = measurement_->channels();
  const Elements& model_state = measurement_->state_elements();
  n_ = states.size();
  nu_ = inputs.size();
  m_ = channels.size();
  ctx.declare_input(input_in_, "input", {}, nu_ > 0);
  // Sizes first: everything below indexes with them (other parameter problems are reported
  // together at the end).
  bool sizes_ok = true;
  if (n_ < 1 || n_ > static_cast<std::size_t>(kMaxStates)) {
    sizes_ok = false;
    params.fail("process", "the process model has " + std::to_string(n_) + " states; 1 to " +
                               std::to_string(kMaxStates) + " are supported");
  }
  if (nu_ > static_cast<std::size_t>(kMaxInputs)) {
    sizes_ok = false;
    params.fail("process", "the process model has " + std::to_string(nu_) + " inputs; at most " +
                               std::to_string(kMaxInputs) + " are supported");
  }
  if (m_ < 1 || m_ > static_cast<std::size_t>(kMaxChannels)) {
    sizes_ok = false;
    params.fail("measurement", "the measurement model has " + std::to_string(m_) + " channels; 1 to " +
                                   std::to_string(kMaxChannels) + " are supported");
  }
  if (model_state.size() > static_cast<std::size_t>(kMaxStates)) {
    sizes_ok = false;
    params.fail("measurement", "the measurement model depends on more than " + std::to_string(kMaxStates) + " elements");
  }
  if (!sizes_ok) return Status::error("invalid parameters");

  // What h depends on: process states first, then process inputs.
  measurement_state_.clear();
  for (const Element& e : model_state) {
    ElementSource source;
    auto in_states = std::find_if(states.begin(), states.end(), [&](const Element& s) { return s.name == e.name; });
    auto in_inputs = std::find_if(inputs.begin(), inputs.end(), [&](const Element& s) { return s.name == e.name; });
    if (in_states != states.end()) {
      source.index = static_cast<std::size_t>(in_states - states.begin());
      if (canonical_unit(in_states->unit) != canonical_unit(e.unit)) {
        params.fail("measurement", "the measurement model's '" + e.name + "' is in " + e.unit +
                                       ", the process state's in " + in_states->unit);
      }
    } else if (in_inputs != inputs.end()) {
      source.from_input = true;
      source.index = static_cast<std::size_t>(in_inputs - inputs.begin());
      if (canonical_unit(in_inputs->unit) != canonical_unit(e.unit)) {
        params.fail("measurement", "the measurement model's '" + e.name + "' is in " + e.unit +
                                       ", the process input's in " + in_inputs->unit);
      }
    } else {
      params.fail("measurement", "the measurement model depends on '" + e.name + "' [" + e.unit +
                                     "], which is neither a process state (" + element_list(states) +
                                     ") nor a process input (" + element_list(inputs) + ")");
    }
    measurement_state_.push_back(source);
  }

  measurement_reads_leading_states_ = true;
  for (std::size_t j = 0; j < measurement_state_.size(); ++j) {
    if (measurement_state_[j].from_input || measurement_state_[j].index != j) measurement_reads_leading_states_ = false;
  }

  // Inputs, by name.
  std::string why;
  if (const Elements* source = ctx.input_source("measurement"); source == nullptr) {
    params.fail("inputs", "the measurement input must be connected to a configured block's output providing " +
                              element_list(channels));
  } else if (!pick_elements(channels, *source, measurement_index_, why)) {
    params.fail("inputs", "measurement: " + why);
  }
  if (nu_ > 0) {
    if (const Elements* source = ctx.input_source("input"); source == nullptr) {
      params.fail("inputs", "the input must be connected to an output providing the process inputs " +
                                element_list(inputs) + " (the values held over the last period)");
    } else if (!pick_elements(inputs, *source, input_index_, why)) {
      params.fail("inputs", "input: " + why);
    }
  }

  // Noise and initial condition.
  const Eigen::MatrixXd q_matrix = covariance_from(params, "q", q, n_, true);
  const Eigen::MatrixXd r_matrix = covariance_from(params, "r", r, m_, false);
  const Eigen::MatrixXd p0_matrix = covariance_from(params, "p0", p0, n_, false);
  if (x0.size() != n_) {
    params.fail("initial_state", "expected " + std::to_string(n_) + " numbers (" + element_list(states) + "), got " +
                                     std::to_string(x0.size()));
  }
  for (double v : x0) {
    if (!std::isfinite(v)) params.fail("initial_state", "must be finite");
  }
  if (!params.ok()) return Status::error("invalid parameters");

  q_configured_ = q_matrix;
  Q_ = noise_basis_ == NoiseBasis::per_second ? StateMatrix(q_matrix * dt_) : StateMatrix(q_matrix);
  R_ = r_matrix;
  P0_ = p0_matrix;
  x0_.resize(static_cast<Eigen::Index>(n_));
  for (std::size_t i = 0; i < n_; ++i) x0_(static_cast<Eigen::Index>(i)) = x0[i];
  x_ = x0_;
  P_ = P0_;
  u_.setZero(static_cast<Eigen::Index>(nu_));
  y_.setZero(static_cast<Eigen::Index>(m_));
  innovation_.setZero(static_cast<Eigen::Index>(m_));
  innovation_variance_.setZero(static_cast<Eigen::Index>(m_));

  // The model must be finite at the initial condition, or the first cycle would fault.
  {
    std::array<double, kMaxStates> next{};
    std::array<double, kMaxChannels> y{};
    propagate(x0_.data(), next.data());
    measure(x0_.data(), y.data());
    bool finite = true;
    for (std::size_t i = 0; i < n_; ++i) finite = finite && std::isfinite(next[i]);
    for (std::size_t c = 0; c < m_; ++c) finite = finite && std::isfinite(y[c]);
    if (!finite) params.fail("initial_state", "f or h is not finite at the initial state");
  }
  if (Status st = prepare_filter(params); !st) return st;
  if (!params.ok()) return Status::error("invalid parameters");

  Elements stds;
  for (const Element& e : states) stds.push_back({e.name, e.unit});
  ctx.declare_output(state_out_, "state", states);
  ctx.declare_output(std_out_, "std", stds);
  ctx.declare_output(innovation_out_, "innovation", channels);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status ModelEstimator::activate() {
  x_ = x0_;
  P_ = P0_;
  u_.setZero(static_cast<Eigen::Index>(nu_));
  innovation_.setZero(static_cast<Eigen::Index>(m_));
  innovation_variance_.setZero(static_cast<Eigen::Index>(m_));
  first_ = true;
  has_innovation_ = false;
  reset_filter();
  for (std::size_t i = 0; i < n_; ++i) {
    state_out_[i] = x_(static_cast<Eigen::Index>(i));
    std_out_[i] = std::sqrt(P_(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)));
  }
  for (std::size_t c = 0; c < m_; ++c) innovation_out_[c] = 0.0;
  return Status::ok();
}

StepStatus ModelEstimator::step(const Tick& /*tick*/) noexcept {
  for (std::size_t i = 0; i < nu_; ++i) {
    const double v = input_in_[input_index_[i]];
    if (!std::isfinite(v)) return fault("non-finite process input");
    u_(static_cast<Eigen::Index>(i)) = v;
  }
  for (std::size_t c = 0; c < m_; ++c) {
    const double v = measurement_in_[measurement_index_[c]];
    if (!std::isfinite(v)) return fault("non-finite measurement");
    y_(static_cast<Eigen::Index>(c)) = v;
  }
  if (filter_cycle(first_) != StepStatus::ok) {
    has_innovation_ = false;
    return StepStatus::fault;
  }
  first_ = false;
  has_innovation_ = true;
  for (std::size_t i = 0; i < n_; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    state_out_[i] = x_(k);
    std_out_[i] = std::sqrt(std::max(P_(k, k), 0.0));
  }
  for (std::size_t c = 0; c < m_; ++c) innovation_out_[c] = innovation_(static_cast<Eigen::Index>(c));
  return StepStatus::ok;
}

StateLayout ModelEstimator::state_layout() const {
  StateLayout layout;
  if (process_) layout.elements = process_->process_state();
  layout.covariance = true;
  return layout;
}

void ModelEstimator::export_state(double* values, double* covariance) const noexcept {
  for (std::size_t i = 0; i < n_; ++i) {
    const auto a = static_cast<Eigen::Index>(i);
    values[i] = x_(a);
    if (covariance == nullptr) continue;
    for (std::size_t j = 0; j < n_; ++j) covariance[i * n_ + j] = P_(a, static_cast<Eigen::Index>(j));
  }
}

void ModelEstimator::import_state(const double* values, const double* covariance,
                                  const std::uint8_t* present) noexcept {
  std::array<bool, kMaxStates> given{};
  StateVector x = x0_;
  for (std::size_t i = 0; i < n_; ++i) {
    given[i] = present[i] != 0 && std::isfinite(values[i]);
    if (given[i]) x(static_cast<Eigen::Index>(i)) = values[i];
  }
  StateMatrix P = P0_;
  if (covariance != nullptr) {
    for (std::size_t i = 0; i < n_; ++i) {
      for (std::size_t j = 0; j < n_; ++j) {
        const auto a = static_cast<Eigen::Index>(i);
        const auto b = static_cast<Eigen::Index>(j);
        if (given[i] && given[j]) {
          P(a, b) = covariance[i * n_ + j];
        } else if (given[i] != given[j]) {
          P(a, b) = 0.0;  // no correlation between a handed-over element and an initialised one
        }
      }
    }
  }
  // Symmetric positive definite whatever was handed over: symmetrised; if that is not finite or
  // Cholesky fails, the diagonal (p0 where it is not finite and > 0).
  x_ = x;
  P_ = estimator::usable_covariance(P, [this](Eigen::Index i) { return P0_(i, i); });
  first_ = false;  // the next step predicts from the import
  reset_filter();
}

bool ModelEstimator::innovation(double* residual, double* variance) const noexcept {
  if (!has_innovation_) return false;
  for (std::size_t c = 0; c < m_; ++c) {
    residual[c] = innovation_(static_cast<Eigen::Index>(c));
    variance[c] = innovation_variance_(static_cast<Eigen::Index>(c));
  }
  return true;
}

void ModelEstimator::measure_gathered(const double* x, double* y) const noexcept {
  std::array<double, kMaxStates + kMaxInputs> model_state;  // the first measurement_state_.size() are set
  gather_measurement_state(x, u_.data(), model_state.data());
  measurement_->evaluate(model_state.data(), y);
}

void ModelEstimator::gather_measurement_state(const double* x, const double* u, double* model_state) const noexcept {
  for (std::size_t j = 0; j < measurement_state_.size(); ++j) {
    const ElementSource& s = measurement_state_[j];
    model_state[j] = s.from_input ? u[s.index] : x[s.index];
  }
}

}  // namespace lode::plugins::nonlinear
