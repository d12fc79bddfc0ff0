#include "kalman.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cstdio>
#include <string>

#include "estimator/describe_json.hpp"
#include "estimator/per_axis.hpp"
#include "estimator/usable_covariance.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace kalman {

template <int N>
SteadyState<N> steady_state(const AxisModel<N>& model, double r, double p0) {
  using Matrix = typename AxisModel<N>::Matrix;
  using Vector = typename AxisModel<N>::Vector;
  SteadyState<N> result;
  const Matrix process_noise = model.process_noise();
  Matrix prior_cov = p0 * Matrix::Identity();
  Vector previous_gain = Vector::Zero();
  for (int iteration = 1; iteration <= kRiccatiMaxIterations; ++iteration) {
    Vector gain;
    Matrix next;
    covariance_step(model, process_noise, prior_cov, r, gain, next);
    result.gain = gain;
    result.prior_cov = prior_cov;
    result.iterations = iteration;
    if (!gain.allFinite() || !next.allFinite()) break;
    // Converged when no gain element moved by more than kRiccatiTolerance of itself.
    if (iteration > 1 && estimator::settled(gain, previous_gain, kRiccatiTolerance)) {
      result.converged = true;
      break;
    }
    previous_gain = gain;
    prior_cov = next;
  }

  // A-priori error dynamics e^-_{k+1} = Phi (I - K H) e^-_k.
  result.poles = estimator::error_poles(model.phi, result.gain);
  return result;
}

template SteadyState<2> steady_state<2>(const AxisModel<2>&, double, double);
template SteadyState<3> steady_state<3>(const AxisModel<3>&, double, double);

}  // namespace kalman

namespace {

using estimator::matrix_json;
using estimator::per_axis;
using estimator::vector_values;
using kalman::kMaxAxes;

}  // namespace

Status KalmanEstimator::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();

  const std::string motion = params.choice(
      "motion", {"constant_acceleration", "constant_velocity"}, std::string_view("constant_acceleration"));
  motion_ = motion == "constant_velocity" ? kalman::Motion::constant_velocity
                                          : kalman::Motion::constant_acceleration;
  const std::string output = params.choice("output", {"predicted", "filtered"}, std::string_view("predicted"));
  timing_ = output == "filtered" ? kalman::OutputTiming::filtered : kalman::OutputTiming::predicted;
  initialize_from_first_measurement_ = params.flag("initialize_from_first_measurement", true);
  invalid_measurement_ = estimator::read_invalid_measurement(params);

  ctx.declare_input(measurement_, "measurement", {}, true);
  ctx.declare_input(covariance_, "covariance", {}, false);

  // The measurement's source fixes the number of axes and the output names and units.
  measurement_elements_ = estimator::measured_axes(ctx);
  axes_ = measurement_elements_.size();

  // Read every key first (so none is reported as unknown), then check sizes against n.
  q_ = params.numbers("q");
  p0_ = params.numbers("p0", std::vector<double>{1e-8});
  r_ = params.numbers("r", std::vector<double>{});
  if (axes_ > 0 && params.has("q")) {
    q_ = per_axis(params, "q", q_, axes_);
    p0_ = per_axis(params, "p0", p0_, axes_);
    if (!r_.empty()) r_ = per_axis(params, "r", r_, axes_);
  }
  for (double q : q_) {
    if (q < 0.0) params.fail("q", "Q_k (eq. 4.41) must be >= 0, got " + number_text(q));
  }
  for (double p0 : p0_) {
    if (!(p0 > 0.0)) params.fail("p0", "P0 = p0 I must be positive definite, got p0 = " + number_text(p0));
  }
  for (double r : r_) {
    if (!(r > 0.0)) params.fail("r", "measurement variance must be > 0, got " + number_text(r));
  }

  const Elements* covariance_source = ctx.input_source("covariance");
  if (covariance_source != nullptr && covariance_source->size() != axes_ * axes_) {
    params.fail("inputs", "covariance must have n*n = " + std::to_string(axes_ * axes_) +
                              " elements (row-major R_k, eq. 4.28), got " +
                              std::to_string(covariance_source->size()));
  }
  if (r_.empty() && covariance_source == nullptr) {
    params.fail("r",
                "no measurement variance: give r (per-axis variance, e.g. 2.2e-10 m^2) or connect the "
                "covariance input (R_k from estimator.glsdc)");
  }

  if (!params.ok()) return Status::error("invalid parameters");

  for (std::size_t i = 0; i < axes_; ++i) {
    if (motion_ == kalman::Motion::constant_acceleration) {
      ca_filters_[i].configure(kalman::AxisModel<3>::make(period_s_, q_[i]), p0_[i]);
    } else {
      cv_filters_[i].configure(kalman::AxisModel<2>::make(period_s_, q_[i]), p0_[i]);
    }
  }

  outputs_.declare(ctx, measurement_elements_, motion_ == kalman::Motion::constant_acceleration);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status KalmanEstimator::activate() {
  use_covariance_input_ = covariance_.connected();
  if (use_covariance_input_ && covariance_.size() != axes_ * axes_) {
    return Status::error("estimator.kalman: the covariance input has " + std::to_string(covariance_.size()) +
                         " elements, expected " + std::to_string(axes_ * axes_));
  }
  if (!use_covariance_input_ && r_.empty()) {
    return Status::error("estimator.kalman: no measurement variance: give r or connect the covariance input");
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    ca_filters_[i].reset();
    cv_filters_[i].reset();
    start_at_measurement_[i] = initialize_from_first_measurement_;
  }
  outputs_.clear(axes_);
  has_innovation_ = false;
  return Status::ok();
}

StepStatus KalmanEstimator::step(const Tick& /*tick*/) noexcept {
  // Check every input before touching any axis, so a fault leaves the filter as it was.
  const bool coast_on_invalid = invalid_measurement_ == kalman::InvalidMeasurement::predict;
  // Locals: the stores below could, as far as the compiler knows, change the members.
  const std::size_t axes = axes_;
  const double* measurement = measurement_.data();
  // R(i,i) at i * (axes + 1) of the covariance input, else r[i].
  const double* variances = use_covariance_input_ ? covariance_.data() : r_.data();
  const std::size_t stride = use_covariance_input_ ? axes + 1 : 1;
  for (std::size_t i = 0; i < axes; ++i) {
    const double r = variances[i * stride];
    valid_[i] = true;
    if (!std::isfinite(measurement[i])) {
      if (!coast_on_invalid) {
        has_innovation_ = false;
        return fault("non-finite measurement");
      }
      valid_[i] = false;
    }
    if (!(r > 0.0) || !std::isfinite(r)) {
      if (!coast_on_invalid) {
        has_innovation_ = false;
        return fault("measurement variance R(i,i) <= 0 or not finite");
      }
      valid_[i] = false;
    }
    variance_[i] = r;
  }
  const StepStatus status =
      motion_ == kalman::Motion::constant_acceleration ? run(ca_filters_) : run(cv_filters_);
  if (status != StepStatus::ok) has_innovation_ = false;
  return status;
}

template <int N>
StepStatus KalmanEstimator::run(std::array<kalman::AxisFilter<N>, kMaxAxes>& filters) noexcept {
  // Every axis is computed first and committed only if all are finite.
  std::array<typename kalman::AxisFilter<N>::Cycle, kMaxAxes> cycles;
  bool all_updated = true;
  const std::size_t axes = axes_;
  const double* measurement = measurement_.data();
  for (std::size_t i = 0; i < axes; ++i) {
    const bool finite = valid_[i] ? filters[i].compute_update(measurement[i], variance_[i],
                                                              start_at_measurement_[i], cycles[i])
                                  : filters[i].compute_coast(cycles[i]);
    if (!finite) return fault("Kalman update gave a non-finite state or covariance");
    all_updated = all_updated && valid_[i];
  }
  const bool predicted = timing_ == kalman::OutputTiming::predicted;
  for (std::size_t i = 0; i < axes; ++i) {
    kalman::AxisFilter<N>& filter = filters[i];
    filter.commit(cycles[i]);
    if (valid_[i]) start_at_measurement_[i] = false;
    const auto& x = predicted ? filter.predicted() : filter.filtered();
    outputs_.write<N>(i, x, filter.innovation());  // innovation 0 on a coasting axis: the output stays finite
  }
  has_innovation_ = all_updated;
  return StepStatus::ok;
}

StateLayout KalmanEstimator::state_layout() const {
  return estimator::axis_state_layout(measurement_elements_, states_per_axis());
}

template <int N>
void KalmanEstimator::export_axes(const std::array<kalman::AxisFilter<N>, kMaxAxes>& filters, double* values,
                                  double* covariance) const noexcept {
  estimator::export_axes<N>(
      axes_, [&](std::size_t i) -> const auto& { return filters[i].predicted(); },
      [&](std::size_t i) -> const auto& { return filters[i].prior_covariance(); }, values, covariance);
}

void KalmanEstimator::export_state(double* values, double* covariance) const noexcept {
  if (motion_ == kalman::Motion::constant_acceleration) {
    export_axes(ca_filters_, values, covariance);
  } else {
    export_axes(cv_filters_, values, covariance);
  }
}

template <int N>
void KalmanEstimator::import_axes(std::array<kalman::AxisFilter<N>, kMaxAxes>& filters, const double* values,
                                  const double* covariance, const std::uint8_t* present) noexcept {
  for (std::size_t i = 0; i < axes_; ++i) {
    // The block's own initial values (activate(): x^- = 0, P^- = p0 I) where nothing usable
    // is given; a non-finite value counts as absent.
    const double p0 = filters[i].p0();
    const estimator::ImportedAxis<N> in = estimator::import_axis<N>(i, axes_, values, covariance, present, p0);
    filters[i].set_prior(in.state, estimator::usable_covariance(in.covariance, [p0](Eigen::Index) { return p0; }));
    // The imported state is the prior: no start from the first measurement, unless the
    // position itself was not given (then the next measurement still places it).
    start_at_measurement_[i] = initialize_from_first_measurement_ && !in.position_given();
  }
}

void KalmanEstimator::import_state(const double* values, const double* covariance,
                                   const std::uint8_t* present) noexcept {
  if (motion_ == kalman::Motion::constant_acceleration) {
    import_axes(ca_filters_, values, covariance, present);
  } else {
    import_axes(cv_filters_, values, covariance, present);
  }
}

template <int N>
bool KalmanEstimator::innovation_axes(const std::array<kalman::AxisFilter<N>, kMaxAxes>& filters, double* residual,
                                      double* variance) const noexcept {
  if (!has_innovation_) return false;
  for (std::size_t i = 0; i < axes_; ++i) {
    residual[i] = filters[i].innovation();
    variance[i] = filters[i].innovation_variance();
  }
  return true;
}

bool KalmanEstimator::innovation(double* residual, double* variance) const noexcept {
  return motion_ == kalman::Motion::constant_acceleration ? innovation_axes(ca_filters_, residual, variance)
                                                          : innovation_axes(cv_filters_, residual, variance);
}

template <int N>
void KalmanEstimator::describe_axes(const std::array<kalman::AxisFilter<N>, kMaxAxes>& filters,
                                    Json& out) const {
  Json axes = Json::array();
  for (std::size_t i = 0; i < axes_; ++i) {
    const kalman::AxisModel<N>& model = filters[i].model();
    const Element& e = measurement_elements_[i];
    Json axis = Json::object();
    axis["name"] = e.name;
    axis["unit"] = e.unit;
    axis["q"] = q_[i];
    axis["q_unit"] = e.unit + (N == 3 ? "^2/s^6" : "^2/s^4");
    axis["p0"] = p0_[i];
    axis["phi"] = matrix_json(model.phi);
    axis["upsilon"] = vector_values(model.upsilon);
    axis["process_noise"] = matrix_json(model.process_noise());
    if (r_.empty()) {
      axis["steady_state"] = "needs a constant r (R_k comes from the covariance input)";
    } else {
      const kalman::SteadyState<N> ss = kalman::steady_state(model, r_[i], p0_[i]);
      Json s = Json::object();
      s["r"] = r_[i];
      s["gain"] = vector_values(ss.gain);
      std::vector<std::string> units{"1", "1/s", "1/s^2"};
      Json gain_units = Json::array();
      for (int k = 0; k < N; ++k) gain_units.push(units[static_cast<std::size_t>(k)]);
      s["gain_units"] = std::move(gain_units);
      s["prior_covariance"] = matrix_json(ss.prior_cov);
      s["converged"] = ss.converged;
      s["iterations"] = ss.iterations;
      s["tolerance"] = "relative change of every gain element <= 1e-12 between iterations";
      s["error_poles_z"] = estimator::error_poles_json(ss.poles, period_s_);
      axis["steady_state"] = std::move(s);
    }
    axes.push(std::move(axis));
  }
  out["axes"] = std::move(axes);
}

void KalmanEstimator::describe(Json& out) const {
  out["motion"] = motion_ == kalman::Motion::constant_acceleration ? "constant_acceleration" : "constant_velocity";
  out["output"] = timing_ == kalman::OutputTiming::predicted ? "predicted (x^-_{k+1})" : "filtered (x^+_k)";
  out["initialize_from_first_measurement"] = initialize_from_first_measurement_;
  out["invalid_measurement"] = estimator::invalid_measurement_text(invalid_measurement_);
  out["period_s"] = period_s_;
  out["measurement_variance"] = r_.empty() ? "covariance input (diagonal of R_k)"
                                           : "covariance input if connected, else r";
  out["covariance_update"] = "Joseph form, symmetrised after propagation";
  if (motion_ == kalman::Motion::constant_acceleration) {
    describe_axes(ca_filters_, out);
  } else {
    describe_axes(cv_filters_, out);
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"motion", "text", "constant_acceleration",
     "constant_acceleration (3 states per axis, Phi/Upsilon eq. 4.39) or constant_velocity (2 states)"},
    {"q", "list<number>", nullptr,
     "Q_k of eq. 4.41 per axis (or one number for all): jerk variance [unit^2/s^6] for "
     "constant_acceleration, acceleration variance [unit^2/s^4] for constant_velocity; >= 0"},
    {"p0", "number|list<number>", "1e-8", "initial covariance P0 = p0 I per axis (thesis: 1e-8 for all states)"},
    {"r", "number|list<number>", "none",
     "constant measurement variance per axis [unit^2]; used when the covariance input is not connected "
     "and for the steady-state gains in describe()"},
    {"output", "text", "predicted", "predicted (x^-_{k+1}, as the thesis outputs) or filtered (x^+_k)"},
    {"initialize_from_first_measurement", "bool", "true",
     "position state starts at the first measurement (false: x^-_0 = 0, the thesis)"},
    {"invalid_measurement", "text", "fault",
     "fault: a non-finite measurement or a non-finite/non-positive R(i,i) faults the step; predict: that axis "
     "skips its measurement update for the cycle (time update only, coasting), innovation() reports no "
     "update for that cycle and the outputs stay finite"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "n <= 6 measured positions, any names and units (e.g. glsdc.pose)"},
    {"covariance", PortDirection::in, "optional n*n row-major R_k (eq. 4.28); the diagonal is used per axis"},
    {"pose", PortDirection::out, "estimated positions, same names and units as the measurement"},
    {"velocity", PortDirection::out, "<name>_dot [<unit>/s]"},
    {"acceleration", PortDirection::out, "<name>_ddot [<unit>/s^2]", "with motion: constant_acceleration"},
    {"innovation", PortDirection::out, "y_k - H x^-_k, same names and units as the measurement"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::KalmanEstimator, "estimator.kalman", lode::PluginKind::estimator, "0.1.0",
            "Per-axis linear Kalman filter (constant acceleration or velocity) after the GLSDC, Table III",
            lode::plugins::kParams, lode::plugins::kPorts)
