// Shared by estimator.ukf and estimator.ekf: a recursive estimator of the state of a plugin
// process model x_{k+1} = f(x_k, u_k) (lode::ProcessModel) observed through a plugin
// measurement model y_k = h(x_k) (lode::MeasurementModel), with additive noise
//   x_{k+1} = f(x_k, u_k) + w_k,  E[w w'] = Q_k;    y_k = h(x_k) + n_k,  E[n n'] = R
// (Sensors 2016, 16, 1504, eq. 17; Q and R enter additively in eqs. 24 and 27, so the state is
// not augmented).
//
// Header-only and not a plugin (no CMakeLists.txt here): each estimator includes it with
// `#include "../nonlinear_common/model_estimator.hpp"`. configure()/activate()/describe() run
// on the loader thread; step() and everything it calls on the RT thread, with fixed-capacity
// Eigen storage (at most kMaxStates states, kMaxChannels channels, kMaxInputs inputs).
//
// Wiring, by element name (resolved once, in configure()):
//  - `measurement` input: each channel of the measurement model is taken from the connected
//    output's element of the same name (or by position when the sizes agree);
//  - `input` input: each process input (e.g. coil_voltage [V]) likewise; it carries the input
//    held over the period that just ended, u_{k-1} (e.g. the board's DAC read-back);
//  - each element the measurement model depends on is a process state of that name, or else
//    a process input (so h may depend on u, as the Hall sensor's coil compensation does).
// Cycle k: (k > 0) predict x_{k|k-1} from x_{k-1|k-1} with u_{k-1}; update with y_k; output
// x_{k|k}, sqrt(diag P_{k|k}) and the innovation y_k - h(x_{k|k-1}) (an assumed order: the
// paper's text does not spell out the per-sample order of its loop).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/math/riccati.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins::nonlinear {

inline constexpr int kMaxStates = 12;
inline constexpr int kMaxChannels = 12;
inline constexpr int kMaxInputs = 12;

using StateVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxStates, 1>;
using StateMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxStates, kMaxStates>;
using ChannelVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxChannels, 1>;
using ChannelMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxChannels, kMaxChannels>;
using GainMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxStates, kMaxChannels>;
using ObservationMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxChannels, kMaxStates>;
using InputVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxInputs, 1>;

/// How the configured q is turned into the per-step Q_k.
enum class NoiseBasis {
  per_step,   ///< Q_k = q (a covariance per period)
  per_second  ///< Q_k = q dt (a white-noise intensity [unit^2/s], Euler discretisation)
};

inline std::string element_list(const Elements& elements) {
  std::string out;
  for (const Element& e : elements) out += (out.empty() ? "" : ", ") + e.name + " [" + e.unit + "]";
  return out.empty() ? "(none)" : out;
}

/// The index in `source` of every element of `wanted`: by name (units must be compatible),
/// or by position when no name matches and the sizes agree. Returns false with `why`.
inline bool pick_elements(const Elements& wanted, const Elements& source, std::vector<std::size_t>& index,
                          std::string& why) {
  index.clear();
  bool all_named = true;
  for (const Element& w : wanted) {
    const auto it = std::find_if(source.begin(), source.end(), [&](const Element& s) { return s.name == w.name; });
    if (it == source.end()) {
      all_named = false;
      break;
    }
    if (!units_compatible(it->unit, w.unit)) {
      why = "element '" + w.name + "' is in " + it->unit + ", expected " + w.unit;
      return false;
    }
    index.push_back(static_cast<std::size_t>(it - source.begin()));
  }
  if (all_named) return true;
  index.clear();
  if (source.size() != wanted.size()) {
    why = "needs " + element_list(wanted) + " (by name, or the same number of elements by position); the source has " +
          element_list(source);
    return false;
  }
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    if (!units_compatible(source[i].unit, wanted[i].unit)) {
      why = "element " + std::to_string(i) + " ('" + source[i].name + "') is in " + source[i].unit + ", expected " +
            wanted[i].unit + " for '" + wanted[i].name + "'";
      return false;
    }
    index.push_back(i);
  }
  return true;
}

/// A covariance given as one number (c I), n numbers (its diagonal) or n*n numbers (row-major).
/// Symmetric, and positive definite (or semidefinite when `semidefinite`); problems go to params.
inline Eigen::MatrixXd covariance_from(Params& params, std::string_view key, const std::vector<double>& values,
                                       std::size_t n, bool semidefinite) {
  Eigen::MatrixXd c = Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  const auto N = static_cast<Eigen::Index>(n);
  if (values.size() == 1) {
    c *= values[0];
  } else if (values.size() == n) {
    for (Eigen::Index i = 0; i < N; ++i) c(i, i) = values[static_cast<std::size_t>(i)];
  } else if (values.size() == n * n) {
    for (Eigen::Index i = 0; i < N; ++i)
      for (Eigen::Index j = 0; j < N; ++j) c(i, j) = values[static_cast<std::size_t>(i * N + j)];
  } else {
    params.fail(key, "expected 1, " + std::to_string(n) + " (diagonal) or " + std::to_string(n * n) +
                         " (row-major) numbers, got " + std::to_string(values.size()));
    return c;
  }
  if (!c.allFinite()) {
    params.fail(key, "must be finite");
    return c;
  }
  // Plain loops: Eigen's reductions on dynamic vectors trip g++ 12's -Wnull-dereference at -O2.
  double scale = std::numeric_limits<double>::min();
  double asymmetry = 0.0;
  for (Eigen::Index i = 0; i < N; ++i) {
    for (Eigen::Index j = 0; j < N; ++j) {
      scale = std::max(scale, std::abs(c(i, j)));
      asymmetry = std::max(asymmetry, std::abs(c(i, j) - c(j, i)));
    }
  }
  if (asymmetry > 1e-12 * scale) {
    params.fail(key, "must be symmetric");
    return c;
  }
  const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(c, Eigen::EigenvaluesOnly).eigenvalues();
  double smallest = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < eig.size(); ++i) smallest = std::min(smallest, eig(i));
  if (semidefinite ? smallest < -1e-12 * scale : !(smallest > 0.0)) {
    params.fail(key, std::string("must be positive ") + (semidefinite ? "semidefinite" : "definite") +
                         ", its smallest eigenvalue is " + number_text(smallest));
  }
  return c;
}

template <typename Derived>
Json matrix_json(const Eigen::MatrixBase<Derived>& m) {
  Json rows = Json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    std::vector<double> row;
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push(Json(row));
  }
  return rows;
}

template <typename Derived>
std::vector<double> vector_values(const Eigen::MatrixBase<Derived>& v) {
  std::vector<double> out;
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

/// Where an element the measurement model needs comes from.
struct ElementSource {
  bool from_input = false;  ///< false: a process state
  std::size_t index = 0;
};

/// The common block: models, noise, initial condition, ports, wiring, outputs.
/// Subclasses provide the algorithm (filter_cycle) and its own parameters.
class ModelEstimator : public Block, public EstimatorState {
 public:
  Status configure(ConfigureContext& ctx) final;
  Status activate() final;
  StepStatus step(const Tick& tick) noexcept final;
  void describe(Json& out) const final;

  /// @name Estimator state (hot swap). Layout: the process state's names and units, with the
  /// covariance P. The exported state is what the next step() starts from, x_{k-1|k-1} and
  /// P_{k-1|k-1} (the cycle predicts from it with u_{k-1}, then updates with y_k).
  /// import_state() sets them (absent or non-finite elements: initial_state and p0, with zero
  /// cross terms to the given ones; P symmetrised, and if that is not positive definite its
  /// diagonal alone is kept) and ends the first-cycle case: the next step() predicts from the
  /// import. innovation(): y_k - y^_{k|k-1} and the diagonal of the innovation covariance
  /// (P_yy for the UKF, S = H P^- H' + R for the EKF).
  //@{
  [[nodiscard]] StateLayout state_layout() const final;
  void export_state(double* values, double* covariance) const noexcept final;
  void import_state(const double* values, const double* covariance, const std::uint8_t* present) noexcept final;
  [[nodiscard]] std::size_t innovation_size() const final { return m_; }
  bool innovation(double* residual, double* variance) const noexcept final;
  //@}

  /// @name Read access (tests, describe).
  //@{
  [[nodiscard]] std::size_t state_size() const { return n_; }
  [[nodiscard]] std::size_t channel_count() const { return m_; }
  [[nodiscard]] const StateVector& estimate() const { return x_; }
  [[nodiscard]] const StateMatrix& covariance() const { return P_; }
  [[nodiscard]] const StateMatrix& process_noise() const { return Q_; }
  [[nodiscard]] const ChannelMatrix& measurement_noise() const { return R_; }
  //@}

 protected:
  /// Read the algorithm's own keys (before the common validation finishes).
  virtual void read_filter_params(Params& params) = 0;
  /// Sizes, models and noise are known and valid: derive the algorithm's constants.
  virtual Status prepare_filter(Params& params) = 0;
  /// activate() or import_state(): x_ and P_ were set (initial condition or warm start).
  virtual void reset_filter() noexcept {}
  /// One cycle (see the file comment). On success x_, P_, innovation_ and
  /// innovation_variance_ hold the new values; on
  /// a fault they are left unchanged and fault(reason) has been called.
  virtual StepStatus filter_cycle(bool first) noexcept = 0;
  virtual void describe_filter(Json& out) const = 0;

  /// x_next = f(x, u_) over one period.
  void propagate(const double* x, double* x_next) const noexcept { process_->propagate(dt_, x, u_.data(), x_next); }
  void propagate(const double* x, const double* u, double* x_next) const noexcept {
    process_->propagate(dt_, x, u, x_next);
  }
  /// y = h(x) with the measurement model's inputs taken from x and u_.
  void measure(const double* x, double* y) const noexcept {
    std::array<double, kMaxStates + kMaxInputs> model_state{};
    gather_measurement_state(x, u_.data(), model_state.data());
    measurement_->evaluate(model_state.data(), y);
  }
  /// y = h(x) and H = dh/dx (m x n; the columns of elements taken from u are dropped).
  void measure_jacobian(const double* x, double* y, ObservationMatrix& H) const noexcept {
    measure_jacobian(x, u_.data(), y, H);
  }
  void measure_jacobian(const double* x, const double* u, double* y, ObservationMatrix& H) const noexcept {
    std::array<double, kMaxStates + kMaxInputs> model_state{};
    std::array<double, kMaxChannels*(kMaxStates + kMaxInputs)> row_major{};
    gather_measurement_state(x, u, model_state.data());
    measurement_->jacobian(model_state.data(), y, row_major.data());
    H.setZero(static_cast<Eigen::Index>(m_), static_cast<Eigen::Index>(n_));
    const std::size_t width = measurement_state_.size();
    for (std::size_t c = 0; c < m_; ++c)
      for (std::size_t j = 0; j < width; ++j)
        if (!measurement_state_[j].from_input)
          H(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(measurement_state_[j].index)) += row_major[c * width + j];
  }
  /// The model's analytic F = df/dx at (x, u), or false if it has none.
  bool analytic_process_jacobian(const double* x, const double* u, StateMatrix& F) const noexcept {
    std::array<double, kMaxStates * kMaxStates> row_major{};
    if (!process_->process_jacobian(dt_, x, u, row_major.data())) return false;
    F.resize(static_cast<Eigen::Index>(n_), static_cast<Eigen::Index>(n_));
    for (std::size_t i = 0; i < n_; ++i)
      for (std::size_t j = 0; j < n_; ++j)
        F(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = row_major[i * n_ + j];
    return true;
  }
  /// Central differences: F(:, j) = (f(x + h e_j) - f(x - h e_j)) / 2h with
  /// h = eps^(1/3) max(|x_j|, scale_j) (scale_j: e.g. sqrt(P_jj)), truncation O(h^2).
  void numerical_process_jacobian(const double* x, const double* u, const StateVector& scale,
                                  StateMatrix& F) const noexcept {
    const double step = std::cbrt(std::numeric_limits<double>::epsilon());
    std::array<double, kMaxStates> plus{}, minus{}, f_plus{}, f_minus{};
    F.resize(static_cast<Eigen::Index>(n_), static_cast<Eigen::Index>(n_));
    for (std::size_t j = 0; j < n_; ++j) {
      const double h = step * std::max({std::abs(x[j]), scale(static_cast<Eigen::Index>(j)), 1e-12});
      for (std::size_t i = 0; i < n_; ++i) plus[i] = minus[i] = x[i];
      plus[j] += h;
      minus[j] -= h;
      const double width = plus[j] - minus[j];  // the representable step
      propagate(plus.data(), u, f_plus.data());
      propagate(minus.data(), u, f_minus.data());
      for (std::size_t i = 0; i < n_; ++i)
        F(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = (f_plus[i] - f_minus[i]) / width;
    }
  }

  // Sizes and constants.
  std::size_t n_ = 0;   ///< states
  std::size_t m_ = 0;   ///< measurement channels
  std::size_t nu_ = 0;  ///< process inputs
  double dt_ = 0.0;
  StateMatrix Q_;       ///< per step
  ChannelMatrix R_;
  StateVector x0_;
  StateMatrix P0_;

  // Models.
  ModelPtr<ProcessModel> process_;
  ModelPtr<MeasurementModel> measurement_;

  // Estimate (the subclass updates these in filter_cycle()).
  StateVector x_;
  StateMatrix P_;
  ChannelVector y_;           ///< this cycle's measurement
  ChannelVector innovation_;  ///< y_k - h(x_{k|k-1})
  ChannelVector innovation_variance_;  ///< diagonal of the innovation covariance of that update
  InputVector u_;             ///< the input held over the last period

 private:
  void gather_measurement_state(const double* x, const double* u, double* model_state) const noexcept {
    for (std::size_t j = 0; j < measurement_state_.size(); ++j) {
      const ElementSource& s = measurement_state_[j];
      model_state[j] = s.from_input ? u[s.index] : x[s.index];
    }
  }
  void describe_linearisation(Json& out) const;

  std::string process_name_;
  std::string measurement_name_;
  NoiseBasis noise_basis_ = NoiseBasis::per_step;
  Eigen::MatrixXd q_configured_;
  std::vector<ElementSource> measurement_state_;
  std::vector<std::size_t> measurement_index_;  ///< channel c is element measurement_index_[c] of the input
  std::vector<std::size_t> input_index_;
  bool first_ = true;
  bool has_innovation_ = false;  ///< the last step made a measurement update

  InputPort measurement_in_;
  InputPort input_in_;
  OutputPort state_out_;
  OutputPort std_out_;
  OutputPort innovation_out_;
};

inline Status ModelEstimator::configure(ConfigureContext& ctx) {
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

inline Status ModelEstimator::activate() {
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

inline StepStatus ModelEstimator::step(const Tick& /*tick*/) noexcept {
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

inline StateLayout ModelEstimator::state_layout() const {
  StateLayout layout;
  if (process_) layout.elements = process_->process_state();
  layout.covariance = true;
  return layout;
}

inline void ModelEstimator::export_state(double* values, double* covariance) const noexcept {
  for (std::size_t i = 0; i < n_; ++i) {
    const auto a = static_cast<Eigen::Index>(i);
    values[i] = x_(a);
    if (covariance == nullptr) continue;
    for (std::size_t j = 0; j < n_; ++j) covariance[i * n_ + j] = P_(a, static_cast<Eigen::Index>(j));
  }
}

inline void ModelEstimator::import_state(const double* values, const double* covariance,
                                         const std::uint8_t* present) noexcept {
  const auto n = static_cast<Eigen::Index>(n_);
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
  // Symmetric positive definite whatever was handed over: symmetrise; if that is not finite or
  // Cholesky fails, keep the diagonal (p0 where it is not finite and > 0).
  StateMatrix sym = P;
  sym = (0.5 * (P + P.transpose())).eval();
  bool usable = sym.allFinite();
  if (usable) {
    const Eigen::LLT<StateMatrix> llt(sym);
    usable = llt.info() == Eigen::Success;
  }
  if (!usable) {
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = 0; j < n; ++j) {
        const double v = P(i, i);
        sym(i, j) = i != j ? 0.0 : (std::isfinite(v) && v > 0.0 ? v : P0_(i, i));
      }
    }
  }
  x_ = x;
  P_ = sym;
  first_ = false;  // the next step predicts from the import
  reset_filter();
}

inline bool ModelEstimator::innovation(double* residual, double* variance) const noexcept {
  if (!has_innovation_) return false;
  for (std::size_t c = 0; c < m_; ++c) {
    residual[c] = innovation_(static_cast<Eigen::Index>(c));
    variance[c] = innovation_variance_(static_cast<Eigen::Index>(c));
  }
  return true;
}

inline void ModelEstimator::describe_linearisation(Json& out) const {
  // The filter linearised at the initial state (u = 0) and run to steady state: the gains and
  // error poles it settles to near there (lode::math::steady_state_kalman).
  StateMatrix F;
  const std::array<double, kMaxInputs> no_input{};  // not u_: the RT thread may be writing it
  const bool analytic = analytic_process_jacobian(x0_.data(), no_input.data(), F);
  if (!analytic) {
    StateVector scale = P0_.diagonal().cwiseMax(0.0).cwiseSqrt();
    numerical_process_jacobian(x0_.data(), no_input.data(), scale, F);
  }
  ObservationMatrix H;
  std::array<double, kMaxChannels> y{};
  measure_jacobian(x0_.data(), no_input.data(), y.data(), H);
  Json lin = Json::object();
  lin["at"] = "initial_state, u = 0";
  lin["F"] = matrix_json(F);
  lin["F_source"] = analytic ? "analytic (process model)" : "central differences";
  lin["H"] = matrix_json(H);
  const Expected<math::SteadyKalman> kf =
      math::steady_state_kalman(Eigen::MatrixXd(F), Eigen::MatrixXd(H), Eigen::MatrixXd(Q_), Eigen::MatrixXd(R_));
  if (!kf) {
    lin["steady_state"] = "not available: " + kf.error();
  } else {
    const math::SteadyKalman& s = kf.value();
    Json ss = Json::object();
    ss["gain"] = matrix_json(s.K);
    ss["posterior_std"] = vector_values(s.P_post.diagonal().cwiseMax(0.0).cwiseSqrt().eval());
    // x_{k|k} error dynamics e_k = (I - K H) F e_{k-1}.
    const Eigen::MatrixXd closed =
        (Eigen::MatrixXd::Identity(F.rows(), F.cols()) - s.K * Eigen::MatrixXd(H)) * Eigen::MatrixXd(F);
    Json poles = Json::array();
    const Eigen::VectorXcd z = Eigen::EigenSolver<Eigen::MatrixXd>(closed, false).eigenvalues();
    for (Eigen::Index i = 0; i < z.size(); ++i) {
      Json p = Json::object();
      p["re"] = z(i).real();
      p["im"] = z(i).imag();
      p["abs"] = std::abs(z(i));
      p["continuous_rad_s"] = std::abs(std::log(z(i))) / dt_;
      poles.push(std::move(p));
    }
    ss["error_poles_z"] = std::move(poles);
    lin["steady_state"] = std::move(ss);
  }
  out["linearised"] = std::move(lin);
}

inline void ModelEstimator::describe(Json& out) const {
  out["process"] = process_name_;
  out["measurement"] = measurement_name_;
  out["period_s"] = dt_;
  if (process_) {
    Json states = Json::array();
    for (const Element& e : process_->process_state()) states.push(e.name + " [" + e.unit + "]");
    out["states"] = std::move(states);
    Json inputs = Json::array();
    for (const Element& e : process_->process_inputs()) inputs.push(e.name + " [" + e.unit + "]");
    out["inputs"] = std::move(inputs);
  }
  if (measurement_) {
    Json channels = Json::array();
    for (const Element& e : measurement_->channels()) channels.push(e.name + " [" + e.unit + "]");
    out["channels"] = std::move(channels);
    Json depends = Json::array();
    for (std::size_t j = 0; j < measurement_state_.size(); ++j) {
      const Element& e = measurement_->state_elements()[j];
      depends.push(e.name + (measurement_state_[j].from_input ? " (process input)" : " (process state)"));
    }
    out["measurement_depends_on"] = std::move(depends);
  }
  out["process_noise"] = noise_basis_ == NoiseBasis::per_second ? "per_second: Q_k = q dt" : "per_step: Q_k = q";
  out["q"] = matrix_json(q_configured_);
  out["Q_k"] = matrix_json(Q_);
  out["R"] = matrix_json(R_);
  out["initial_state"] = vector_values(x0_);
  out["p0"] = matrix_json(P0_);
  out["order"] = "cycle k: predict with u_{k-1} (input), update with y_k, output x_{k|k}";
  Json filter = Json::object();
  describe_filter(filter);
  out["filter"] = std::move(filter);
  if (process_ && measurement_ && n_ > 0) describe_linearisation(out);
  if (process_) {
    if (const auto* plant = dynamic_cast<const PlantModel*>(process_.get()); plant != nullptr) {
      Json model = Json::object();
      plant->describe(model);
      out["process_model"] = std::move(model);
    }
  }
  if (measurement_) {
    Json model = Json::object();
    measurement_->describe(model);
    out["measurement_model"] = std::move(model);
  }
}

/// The parameter documentation both estimators share (each plugin lists these in kParams).
#define LODE_MODEL_ESTIMATOR_PARAM_DOCS                                                                      \
  {"process", "text", nullptr, "name of a process model in `models:` (e.g. a plant.suspension entry)"},       \
      {"measurement", "text", nullptr, "name of a measurement model in `models:` (e.g. a sensor.hall_gap)"}, \
      {"q", "list<number>", nullptr,                                                                         \
       "process noise: 1 number (q I), n (diagonal) or n*n (row-major), in state units^2 (per step) or "     \
       "state units^2/s (per_second)"},                                                                      \
      {"process_noise", "text", "per_step", "per_step (Q_k = q) or per_second (Q_k = q dt, an intensity)"},  \
      {"r", "list<number>", nullptr, "measurement noise: 1, m (diagonal) or m*m numbers, channel units^2"},  \
      {"initial_state", "list<number>", nullptr, "x_0, one per process state (eq. 19)"},                     \
      {"p0", "list<number>", nullptr, "P_0: 1, n (diagonal) or n*n numbers, positive definite (eq. 19)"}

#define LODE_MODEL_ESTIMATOR_PORT_DOCS                                                                         \
  {"measurement", PortDirection::in, "the measurement model's channels, taken by name (e.g. hall_direct.gap: gap [m])"},   \
      {"input", PortDirection::in, "the process inputs held over the last period, by name (e.g. stage.truth: coil_voltage)"}, \
      {"state", PortDirection::out, "x_{k|k}, the process model's state elements"},                                        \
      {"std", PortDirection::out, "sqrt(diag P_{k|k}), same names and units as the state"},                                \
      {"innovation", PortDirection::out, "y_k - h(x_{k|k-1}), the measurement channels"}

}  // namespace lode::plugins::nonlinear
