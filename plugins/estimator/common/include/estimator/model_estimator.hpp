// Shared by estimator.ukf and estimator.ekf: a recursive estimator of the state of a plugin
// process model x_{k+1} = f(x_k, u_k) (lode::ProcessModel) observed through a plugin
// measurement model y_k = h(x_k) (lode::MeasurementModel), with additive noise
//   x_{k+1} = f(x_k, u_k) + w_k,  E[w w'] = Q_k;    y_k = h(x_k) + n_k,  E[n n'] = R
// (Sensors 2016, 16, 1504, eq. 17; Q and R enter additively in eqs. 24 and 27, so the state is
// not augmented).
//
// The library lode_estimator_nonlinear (plugins/estimator/common): each estimator links it and
// includes "estimator/model_estimator.hpp". configure()/activate()/describe() run on the loader
// thread; step() and everything it calls on the RT thread, with fixed-capacity Eigen storage
// (at most kMaxStates states, kMaxChannels channels, kMaxInputs inputs).
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

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/estimator_state.hpp"

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

  /// h depends on the first process state and nothing else (e.g. the suspension's gap): its
  /// Jacobian is zero beyond the first column.
  [[nodiscard]] bool measurement_reads_first_state_only() const noexcept {
    return measurement_reads_leading_states_ && measurement_state_.size() == 1;
  }

  /// x_, P_, innovation_ and innovation_variance_ = the cycle's results. From storage sized at
  /// compile time, element by element into the capacity-sized members (already n and m long
  /// since configure()): Eigen's assignment between the two checks and resizes each time.
  template <class X, class Cov, class Innovation, class Variance>
  void commit_estimate(const X& x, const Cov& P, const Innovation& innovation, const Variance& variance) noexcept {
    constexpr int kN = X::SizeAtCompileTime;
    constexpr int kM = Innovation::SizeAtCompileTime;
    if constexpr (kN != Eigen::Dynamic && kM != Eigen::Dynamic) {
      for (int i = 0; i < kN; ++i) x_.data()[i] = x(i);
      for (int i = 0; i < kN * kN; ++i) P_.data()[i] = P.data()[i];  // both column-major, n x n
      for (int c = 0; c < kM; ++c) {
        innovation_.data()[c] = innovation(c);
        innovation_variance_.data()[c] = variance(c);
      }
    } else {
      x_ = x;
      P_ = P;
      innovation_ = innovation;
      innovation_variance_ = variance;
    }
  }

  /// x_next = f(x, u_) over one period.
  void propagate(const double* x, double* x_next) const noexcept { process_->propagate(dt_, x, u_.data(), x_next); }
  void propagate(const double* x, const double* u, double* x_next) const noexcept {
    process_->propagate(dt_, x, u, x_next);
  }
  /// propagate() for `count` states of n_ elements one after another (a sigma-point filter's
  /// points), in one call to the model.
  void propagate_points(const double* x, std::size_t count, double* x_next) const noexcept {
    process_->propagate_points(dt_, x, count, u_.data(), x_next);
  }
  /// y = h(x) with the measurement model's inputs taken from x and u_. Inline: the UKF calls it
  /// for each sigma point, and from this library's object code it would go through the PLT.
  void measure(const double* x, double* y) const noexcept {
    if (measurement_reads_leading_states_) {  // h's state is x's first elements: no copy
      measurement_->evaluate(x, y);
      return;
    }
    measure_gathered(x, y);
  }
  /// measure() for `count` states of n_ elements one after another, the results m_ apart.
  void measure_points(const double* x, std::size_t count, double* y) const noexcept {
    if (measurement_reads_leading_states_) {  // each point's first elements are h's state
      measurement_->evaluate_points(x, n_, count, y);
      return;
    }
    for (std::size_t i = 0; i < count; ++i) measure_gathered(x + i * n_, y + i * m_);
  }
  /// y = h(x) and H = dh/dx (m x n; the columns of elements taken from u are dropped).
  void measure_jacobian(const double* x, double* y, ObservationMatrix& H) const noexcept {
    measure_jacobian(x, u_.data(), y, H);
  }
  void measure_jacobian(const double* x, const double* u, double* y, ObservationMatrix& H) const noexcept {
    measure_jacobian_into(x, u, y, H);
  }
  /// The same into any m x n Eigen storage (e.g. one sized at compile time).
  template <class Observation>
  void measure_jacobian_into(const double* x, const double* u, double* y, Observation& H) const noexcept {
    const std::size_t width = measurement_state_.size();
    // Only the m x width entries the model writes are cleared, not the whole capacity.
    std::array<double, kMaxStates + kMaxInputs> model_state;
    std::array<double, kMaxChannels*(kMaxStates + kMaxInputs)> row_major;
    for (std::size_t i = 0; i < m_ * width; ++i) row_major[i] = 0.0;  // a few: no memset call
    const double* state = x;  // h's state is x's first elements: no copy
    if (!measurement_reads_leading_states_) {
      gather_measurement_state(x, u, model_state.data());
      state = model_state.data();
    }
    measurement_->jacobian(state, y, row_major.data());
    H.setZero(static_cast<Eigen::Index>(m_), static_cast<Eigen::Index>(n_));
    for (std::size_t c = 0; c < m_; ++c)
      for (std::size_t j = 0; j < width; ++j)
        if (!measurement_state_[j].from_input)
          H(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(measurement_state_[j].index)) +=
              row_major[c * width + j];
  }
  /// The model's analytic F = df/dx at (x, u), or false if it has none.
  bool analytic_process_jacobian(const double* x, const double* u, StateMatrix& F) const noexcept {
    return analytic_process_jacobian_into(x, u, F);
  }
  /// The same into any n x n Eigen storage. Forced inline: as a template member in a
  /// position-independent plugin it was called through the PLT on every EKF cycle.
  template <class Jacobian>
  [[gnu::always_inline]] bool analytic_process_jacobian_into(const double* x, const double* u, Jacobian& F) const noexcept {
    constexpr int kSized = Jacobian::RowsAtCompileTime;
    if constexpr (kSized != Eigen::Dynamic) {  // n x n known here: no loops over n_, no memset call
      Eigen::Matrix<double, kSized, kSized, Eigen::RowMajor> row_major;
      row_major.setZero();
      if (!process_->process_jacobian(dt_, x, u, row_major.data())) return false;
      F = row_major;
      return true;
    }
    std::array<double, kMaxStates * kMaxStates> row_major;
    std::fill_n(row_major.begin(), n_ * n_, 0.0);
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
    numerical_process_jacobian_into(x, u, scale, F);
  }
  /// The same into any n x n Eigen storage; scale any Eigen vector of n.
  template <class Scale, class Jacobian>
  void numerical_process_jacobian_into(const double* x, const double* u, const Scale& scale,
                                       Jacobian& F) const noexcept {
    const double step = std::cbrt(std::numeric_limits<double>::epsilon());
    std::array<double, kMaxStates> plus, minus, f_plus, f_minus;  // the first n_ are written before read
    F.resize(static_cast<Eigen::Index>(n_), static_cast<Eigen::Index>(n_));
    for (std::size_t j = 0; j < n_; ++j) {
      const double h = step * std::max({std::abs(x[j]), static_cast<double>(scale(static_cast<Eigen::Index>(j))), 1e-12});
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
  void gather_measurement_state(const double* x, const double* u, double* model_state) const noexcept;
  /// measure() when h reads process inputs or the states in another order.
  void measure_gathered(const double* x, double* y) const noexcept;
  void describe_linearisation(Json& out) const;

  std::string process_name_;
  std::string measurement_name_;
  NoiseBasis noise_basis_ = NoiseBasis::per_step;
  Eigen::MatrixXd q_configured_;
  std::vector<ElementSource> measurement_state_;
  /// h depends on the process state's first elements in their order (e.g. the gap alone).
  bool measurement_reads_leading_states_ = false;
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
