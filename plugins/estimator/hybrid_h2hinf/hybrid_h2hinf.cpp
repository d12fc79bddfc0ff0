#include "hybrid_h2hinf.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>

#include "estimator/describe_json.hpp"
#include "estimator/per_axis.hpp"
#include "estimator/position_gain.hpp"
#include "lode/sdk/math/riccati.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace hybrid {

KalmanDesign design_kalman(const AxisModel& model, double q, double r) {
  KalmanDesign out;
  const math::Matrix phi = model.phi;
  math::Matrix h = math::Matrix::Zero(1, 3);
  h(0, 0) = 1.0;
  const math::Matrix process_noise = model.upsilon * q * model.upsilon.transpose();
  math::Matrix measurement_noise(1, 1);
  measurement_noise(0, 0) = r;
  const Expected<math::SteadyKalman> kf = math::steady_state_kalman(phi, h, process_noise, measurement_noise);
  if (!kf) {
    out.error = kf.error();
    return out;
  }
  out.gain = kf.value().K.col(0);
  out.prior_cov = kf.value().P_prior;
  out.ok = out.gain.allFinite();
  if (!out.ok) out.error = "the steady-state Kalman gain is not finite";
  return out;
}

HinfDesign design_hinf(const AxisModel& model, const HinfWeights& weights, const Matrix3& initial_cov) {
  HinfDesign out;
  const Matrix3 error_weight = weights.error_weight.asDiagonal();
  const Matrix3 process_weight = model.upsilon * weights.process_weight * model.upsilon.transpose();
  Matrix3 information = Matrix3::Zero();  // H' V^-1 H
  information(0, 0) = 1.0 / weights.measurement_weight;
  const Matrix3 identity = Matrix3::Identity();

  // The existence condition P^-1 - theta S + H'V^-1 H > 0 is tested congruently as
  // Lc'(P^-1 - theta S + H'V^-1 H)Lc = I - theta Lc' S Lc + Lc' H'V^-1 H Lc > 0 with P = Lc Lc':
  // no inverse of P, whose entries span 8 decades (1e-8 m^2 ... 1e-1 m^2/s^4 at q = 1e3).
  const auto margin_matrix = [&](const Eigen::LLT<Matrix3>& p_factor) -> Matrix3 {
    const Matrix3 lc = p_factor.matrixL();
    return identity - weights.theta * lc.transpose() * error_weight * lc + lc.transpose() * information * lc;
  };

  Matrix3 p = initial_cov;
  Vector3 previous_gain = Vector3::Zero();
  for (int iteration = 1; iteration <= kRiccatiMaxIterations; ++iteration) {
    out.iterations = iteration;
    Eigen::LLT<Matrix3> p_factor(p);
    if (p_factor.info() != Eigen::Success || !p.allFinite()) {
      out.outcome = p.allFinite() ? HinfDesign::Outcome::infeasible : HinfDesign::Outcome::not_finite;
      return out;
    }
    const Matrix3 margin = margin_matrix(p_factor);
    Eigen::LLT<Matrix3> margin_factor(margin);
    if (margin_factor.info() != Eigen::Success) {
      out.definiteness_margin = Eigen::SelfAdjointEigenSolver<Matrix3>(margin, Eigen::EigenvaluesOnly).eigenvalues()(0);
      out.outcome = HinfDesign::Outcome::infeasible;
      return out;
    }
    // L = (I - theta S P + H'V^-1 H P)^-1; P L = (P^-1 - theta S + H'V^-1 H)^-1 is symmetric.
    const Matrix3 l = (identity - weights.theta * error_weight * p + information * p).inverse();
    Matrix3 p_l = p * l;
    p_l = 0.5 * (p_l + p_l.transpose()).eval();
    const Vector3 gain = p_l.col(0) / weights.measurement_weight;  // K = P L H' V^-1
    Matrix3 next = model.phi * p_l * model.phi.transpose() + process_weight;
    next = 0.5 * (next + next.transpose()).eval();
    if (!gain.allFinite() || !next.allFinite()) {
      out.outcome = HinfDesign::Outcome::not_finite;
      return out;
    }
    if (next.trace() > kDivergenceGrowth * initial_cov.trace()) {
      out.outcome = HinfDesign::Outcome::diverged;
      return out;
    }
    out.gain = gain;
    out.cov = p;
    if (iteration > 1 && estimator::settled(gain, previous_gain, kRiccatiTolerance)) {
      out.definiteness_margin =
          Eigen::SelfAdjointEigenSolver<Matrix3>(margin, Eigen::EigenvaluesOnly).eigenvalues()(0);
      out.outcome = HinfDesign::Outcome::converged;
      return out;
    }
    previous_gain = gain;
    p = next;
  }
  out.outcome = HinfDesign::Outcome::not_converged;
  return out;
}

double max_feasible_theta(const AxisModel& model, HinfWeights weights, const Matrix3& initial_cov) {
  const auto feasible = [&](double theta) {
    weights.theta = theta;
    return design_hinf(model, weights, initial_cov).ok();
  };
  // Bracket by doubling from a scale where theta S is comparable to H'V^-1 H, then bisect.
  double low = 0.0;
  double high = 1.0 / weights.measurement_weight;
  while (feasible(high)) {
    low = high;
    high *= 2.0;
    if (high > 1e300) return std::numeric_limits<double>::infinity();
  }
  while (high - low > 1e-6 * high) {
    const double middle = 0.5 * (low + high);
    (feasible(middle) ? low : high) = middle;
  }
  return low;
}

double error_spectral_radius(const AxisModel& model, const Vector3& gain) {
  const Matrix3 error_dynamics = estimator::i_minus_kh(gain) * model.phi;
  if (!error_dynamics.allFinite()) return std::numeric_limits<double>::infinity();
  return Eigen::EigenSolver<Matrix3>(error_dynamics, false).eigenvalues().cwiseAbs().maxCoeff();
}

bool blended_prior_covariance(const AxisModel& model, const Vector3& gain, double q, double r, Matrix3& cov) noexcept {
  Matrix3 a = model.phi * estimator::i_minus_kh(gain);
  const Vector3 phi_k = model.phi * gain;
  Matrix3 p = (phi_k * r) * phi_k.transpose() + (model.upsilon * q) * model.upsilon.transpose();
  // 64 doublings sum 2^64 terms: converged for any rho(A) < 1 - 1e-18. Stop as soon as the
  // increment no longer changes any element of P (relative to its own diagonal scale).
  constexpr int kMaxDoublings = 64;
  bool converged = false;
  for (int j = 0; j < kMaxDoublings && !converged; ++j) {
    const Matrix3 increment = a * p * a.transpose();
    converged = true;
    for (int row = 0; row < 3 && converged; ++row) {
      for (int col = 0; col < 3 && converged; ++col) {
        const double scale = std::sqrt(std::abs(p(row, row) * p(col, col)));
        converged = std::abs(increment(row, col)) <= 1e-17 * scale;
      }
    }
    p += increment;
    a = (a * a).eval();
    if (!p.allFinite()) return false;
  }
  cov = 0.5 * (p + p.transpose());
  return converged && cov.allFinite();
}

PositionResponse position_response(const AxisModel& model, const Vector3& gain, double t_s) {
  // x^+_k = (I - K H) Phi x^+_{k-1} + K y_k  =>  p^+(z) / y(z) = e1' (z I - A)^-1 z K.
  using Complex = std::complex<double>;
  using ComplexMatrix3 = Eigen::Matrix<Complex, 3, 3>;
  using ComplexVector3 = Eigen::Matrix<Complex, 3, 1>;
  const ComplexMatrix3 a = (estimator::i_minus_kh(gain) * model.phi).cast<Complex>();
  const ComplexVector3 k = gain.cast<Complex>();
  const double nyquist_hz = 0.5 / t_s;
  const auto magnitude = [&](double f_hz) {
    const Complex z = std::polar(1.0, 2.0 * std::numbers::pi * f_hz * t_s);
    const ComplexVector3 x = (z * ComplexMatrix3::Identity() - a).partialPivLu().solve(z * k);
    return std::abs(x(0));
  };
  PositionResponse out;
  out.bandwidth_hz = nyquist_hz;
  constexpr int kPoints = 4000;
  const double f_min = 1e-3;
  double previous_f = f_min;
  double previous_gain = magnitude(f_min);
  bool crossed = false;
  out.peak_db = 20.0 * std::log10(previous_gain);
  out.peak_hz = f_min;
  for (int i = 1; i <= kPoints; ++i) {
    const double f = f_min * std::pow(nyquist_hz / f_min, static_cast<double>(i) / kPoints);
    const double g = magnitude(f);
    const double db = 20.0 * std::log10(g);
    if (db > out.peak_db) {
      out.peak_db = db;
      out.peak_hz = f;
    }
    const double threshold = 1.0 / std::sqrt(2.0);
    if (!crossed && g < threshold) {
      // Interpolate the crossing linearly in log frequency.
      const double s = (previous_gain - threshold) / (previous_gain - g);
      out.bandwidth_hz = previous_f * std::pow(f / previous_f, s);
      crossed = true;
    }
    previous_f = f;
    previous_gain = g;
  }
  return out;
}

}  // namespace hybrid

namespace {

using estimator::matrix_json;
using estimator::per_axis;
using estimator::vector_values;
using hybrid::kMaxAxes;
using hybrid::Vector3;

/// An injected gain list: 3 numbers [position, velocity, acceleration] for every axis, or
/// 3 per axis (axis after axis).
std::vector<Vector3> gains_from_list(Params& params, std::string_view key, const std::vector<double>& values,
                                     std::size_t axes) {
  std::vector<Vector3> out(axes, Vector3::Zero());
  if (values.size() == 3) {
    for (auto& g : out) g = Vector3(values[0], values[1], values[2]);
  } else if (values.size() == 3 * axes) {
    for (std::size_t i = 0; i < axes; ++i) out[i] = Vector3(values[3 * i], values[3 * i + 1], values[3 * i + 2]);
  } else {
    params.fail(key, "expected 3 numbers [position, velocity 1/s, acceleration 1/s^2] for every axis or 3 per "
                     "axis (" + std::to_string(3 * axes) + "), got " + std::to_string(values.size()));
  }
  return out;
}

/// The mixing weights the paper compares (Figs. 7-8), reported by describe().
constexpr std::array<double, 4> kPaperWeights = {0.0, 0.3, 0.8, 1.0};

}  // namespace

Status HybridH2HinfEstimator::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();
  model_ = hybrid::AxisModel::make(period_s_);

  const double d = params.number("d", 1.0);
  const std::string output = params.choice("output", {"filtered", "predicted"}, std::string_view("filtered"));
  timing_ = output == "predicted" ? hybrid::OutputTiming::predicted : hybrid::OutputTiming::filtered;
  initialize_from_first_measurement_ = params.flag("initialize_from_first_measurement", true);
  invalid_measurement_ = estimator::read_invalid_measurement(params);

  ctx.declare_input(measurement_, "measurement", {}, true);
  measurement_elements_ = estimator::measured_axes(ctx);
  axes_ = measurement_elements_.size();

  // Read every key first (so none is reported as unknown), then check them against n.
  q_ = params.numbers("q");
  r_ = params.numbers("r");
  const std::vector<double> kalman_gain_list = params.numbers("kalman_gain", std::vector<double>{});
  const std::vector<double> hinf_gain_list = params.numbers("hinf_gain", std::vector<double>{});
  std::vector<double> theta = params.numbers("hinf_theta", std::vector<double>{});
  const std::vector<double> error_weight = params.numbers("hinf_error_weight", {1.0, 0.0, 0.0}, 3);
  std::vector<double> process_weight = params.numbers("hinf_process_weight", std::vector<double>{});
  std::vector<double> measurement_weight = params.numbers("hinf_measurement_weight", std::vector<double>{});
  kalman_injected_ = !kalman_gain_list.empty();
  hinf_injected_ = !hinf_gain_list.empty();

  if (!(d >= 0.0 && d <= 1.0)) params.fail("d", "the mixing weight of eq. 25 must be in [0, 1], got " + number_text(d));
  if (axes_ == 0) return Status::error("invalid parameters");

  q_ = per_axis(params, "q", q_, axes_);
  r_ = per_axis(params, "r", r_, axes_);
  for (double q : q_) {
    if (!(q > 0.0)) params.fail("q", "Q_k (eq. 27, jerk variance) must be > 0, got " + number_text(q));
  }
  for (double r : r_) {
    if (!(r > 0.0)) params.fail("r", "R_k (eq. 26, measurement variance) must be > 0, got " + number_text(r));
  }
  for (std::size_t i = 0; i < 3; ++i) {
    if (!(error_weight[i] >= 0.0)) {
      params.fail("hinf_error_weight", "the diagonal of S must be >= 0, got " + number_text(error_weight[i]));
    }
  }
  if (!hinf_injected_) {
    if (theta.empty()) {
      params.fail("hinf_theta",
                  "missing: the H-infinity performance level theta (J < 1/theta, eq. 29) is required "
                  "unless hinf_gain injects the gain; the paper's gamma = 10 is infeasible with the "
                  "standard weights (W = Upsilon q Upsilon', V = r), see describe() for the largest "
                  "feasible theta");
    } else {
      theta = per_axis(params, "hinf_theta", theta, axes_);
      for (double t : theta) {
        if (!(t >= 0.0)) params.fail("hinf_theta", "theta must be >= 0 (0 = the Kalman filter), got " + number_text(t));
      }
    }
    process_weight = process_weight.empty() ? q_ : per_axis(params, "hinf_process_weight", process_weight, axes_);
    measurement_weight =
        measurement_weight.empty() ? r_ : per_axis(params, "hinf_measurement_weight", measurement_weight, axes_);
    for (double w : process_weight) {
      if (!(w > 0.0)) params.fail("hinf_process_weight", "W = Upsilon w Upsilon' needs w > 0, got " + number_text(w));
    }
    for (double v : measurement_weight) {
      if (!(v > 0.0)) params.fail("hinf_measurement_weight", "V must be > 0, got " + number_text(v));
    }
  } else {
    for (const char* key : {"hinf_theta", "hinf_process_weight", "hinf_measurement_weight"}) {
      if (params.has(key)) params.fail(key, "not used: hinf_gain injects the H-infinity gain directly");
    }
  }
  std::vector<Vector3> injected_kalman;
  std::vector<Vector3> injected_hinf;
  if (kalman_injected_) injected_kalman = gains_from_list(params, "kalman_gain", kalman_gain_list, axes_);
  if (hinf_injected_) injected_hinf = gains_from_list(params, "hinf_gain", hinf_gain_list, axes_);
  if (!params.ok()) return Status::error("invalid parameters");

  // Gains, axis by axis (eq. 28 and Simon 2001's minimax recursion).
  hinf_weights_.clear();
  for (std::size_t i = 0; i < axes_; ++i) {
    const std::string& name = measurement_elements_[i].name;
    const hybrid::KalmanDesign kalman = hybrid::design_kalman(model_, q_[i], r_[i]);
    if (!kalman.ok) {
      params.fail("q", "axis '" + name + "': no steady-state Kalman gain for q = " + number_text(q_[i]) +
                           ", r = " + number_text(r_[i]) + ": " + kalman.error);
      continue;
    }
    kalman_gain_[i] = kalman_injected_ ? injected_kalman[i] : kalman.gain;
    if (hinf_injected_) {
      hinf_gain_[i] = injected_hinf[i];
      continue;
    }
    hybrid::HinfWeights w;
    w.theta = theta[i];
    w.error_weight = Vector3(error_weight[0], error_weight[1], error_weight[2]);
    w.process_weight = process_weight[i];
    w.measurement_weight = measurement_weight[i];
    hinf_weights_.push_back(w);
    // Start the H-infinity recursion from the Kalman P of the same weights (its theta = 0 solution).
    const hybrid::KalmanDesign start = hybrid::design_kalman(model_, w.process_weight, w.measurement_weight);
    const hybrid::Matrix3 initial = start.ok ? start.prior_cov : hybrid::Matrix3(model_.upsilon * w.process_weight *
                                                                                 model_.upsilon.transpose());
    const hybrid::HinfDesign design = hybrid::design_hinf(model_, w, initial);
    hinf_iterations_[i] = design.iterations;
    if (!design.ok()) {
      const double max_theta = hybrid::max_feasible_theta(model_, w, initial);
      std::string why;
      if (design.outcome == hybrid::HinfDesign::Outcome::infeasible) {
        why = "infeasible: the existence condition P^-1 - theta S + H'V^-1 H > 0 fails at iteration " +
              std::to_string(design.iterations) + " of the H-infinity Riccati recursion";
      } else if (design.outcome == hybrid::HinfDesign::Outcome::diverged) {
        why = "at or beyond the bound: the H-infinity Riccati recursion diverges (P grew by " +
              number_text(hybrid::kDivergenceGrowth) + " in " + std::to_string(design.iterations) + " iterations)";
      } else if (design.outcome == hybrid::HinfDesign::Outcome::not_converged) {
        why = "the H-infinity Riccati recursion did not converge in " +
              std::to_string(hybrid::kRiccatiMaxIterations) + " iterations (theta too close to the bound)";
      } else {
        why = "the H-infinity Riccati recursion produced non-finite values";
      }
      params.fail("hinf_theta", "theta = " + number_text(w.theta) + " for axis '" + name + "' is " + why +
                                    "; the largest feasible theta for this axis with error weight [" +
                                    number_text(error_weight[0]) + ", " + number_text(error_weight[1]) + ", " +
                                    number_text(error_weight[2]) + "], w = " + number_text(w.process_weight) +
                                    ", v = " + number_text(w.measurement_weight) + " is " +
                                    number_text(max_theta));
      continue;
    }
    hinf_gain_[i] = design.gain;
  }
  if (!params.ok()) return Status::error("invalid parameters");

  // The blended filter must be stable at the configured d (the paper's warning on eq. 25).
  for (std::size_t i = 0; i < axes_; ++i) {
    const double rho = hybrid::error_spectral_radius(model_, hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]));
    if (!(rho < 1.0)) {
      params.fail("d", "d = " + number_text(d) + " gives an unstable filter on axis '" + measurement_elements_[i].name +
                           "': rho((I - K H) Phi) = " + number_text(rho) + " >= 1 (eq. 25 blend of two stable gains)");
    }
  }
  d_.store(d, std::memory_order_relaxed);
  if (params.ok() && !update_steady_covariance(d)) {
    params.fail("d", "d = " + number_text(d) + ": the steady prior covariance of the blended filter "
                     "(discrete Lyapunov equation P = A P A' + W) has no finite solution on some axis");
  }

  outputs_.declare(ctx, measurement_elements_, true);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status HybridH2HinfEstimator::activate() {
  for (std::size_t i = 0; i < axes_; ++i) {
    prior_[i].setZero();
    start_at_measurement_[i] = initialize_from_first_measurement_;
    last_innovation_[i] = 0.0;
  }
  outputs_.clear(axes_);
  has_innovation_ = false;
  return Status::ok();
}

bool HybridH2HinfEstimator::update_steady_covariance(double d) noexcept {
  std::array<hybrid::Matrix3, kMaxAxes> cov{};
  for (std::size_t i = 0; i < axes_; ++i) {
    if (!hybrid::blended_prior_covariance(model_, hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]), q_[i], r_[i],
                                          cov[i])) {
      return false;
    }
  }
  steady_cov_ = cov;
  steady_cov_d_ = d;
  return true;
}

double HybridH2HinfEstimator::worst_spectral_radius(double d) const {
  double worst = 0.0;
  for (std::size_t i = 0; i < axes_; ++i) {
    worst = std::max(worst, hybrid::error_spectral_radius(model_, hybrid::blend(d, kalman_gain_[i], hinf_gain_[i])));
  }
  return worst;
}

Status HybridH2HinfEstimator::set_mixing(double d) {
  if (!(d >= 0.0 && d <= 1.0)) {
    return Status::error("estimator.hybrid_h2hinf: d must be in [0, 1] (eq. 25), got " + number_text(d));
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    const double rho = hybrid::error_spectral_radius(model_, hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]));
    if (!(rho < 1.0)) {
      return Status::error("estimator.hybrid_h2hinf: d = " + number_text(d) + " gives an unstable filter on axis '" +
                           measurement_elements_[i].name + "': rho((I - K H) Phi) = " + number_text(rho) +
                           " >= 1; d unchanged");
    }
  }
  d_.store(d, std::memory_order_relaxed);
  return Status::ok();
}

std::vector<Tunable> HybridH2HinfEstimator::tunables() const {
  return {{"d", "1", 0.0, 1.0, false,
           "mixing weight of eq. 25, K = d K^K + (1 - d) K^inf; refused if the blend is unstable"}};
}

double HybridH2HinfEstimator::tunable_value(std::size_t index) const noexcept {
  return index == 0 ? mixing() : 0.0;
}

bool HybridH2HinfEstimator::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index != 0) {
    why = "no such parameter";
    return false;
  }
  if (!(value >= 0.0 && value <= 1.0)) {
    why = "d must be in [0, 1] (eq. 25)";
    return false;
  }
  // Only the gain changes: the state x^+ carries over, so the estimate moves only through the
  // next innovation (no transient beyond the new filter's own response).
  for (std::size_t i = 0; i < axes_; ++i) {
    const double rho = hybrid::error_spectral_radius(model_, hybrid::blend(value, kalman_gain_[i], hinf_gain_[i]));
    if (!(rho < 1.0)) {
      why = "the blended filter is unstable on some axis (rho((I - K H) Phi) >= 1); d unchanged";
      return false;
    }
  }
  d_.store(value, std::memory_order_relaxed);
  return true;
}

StepStatus HybridH2HinfEstimator::step(const Tick& /*tick*/) noexcept {
  // Check every input and compute every axis before touching the state, so that a fault
  // leaves the filter exactly as it was.
  const bool coast_on_invalid = invalid_measurement_ == hybrid::InvalidMeasurement::predict;
  std::array<bool, kMaxAxes> valid{};
  for (std::size_t i = 0; i < axes_; ++i) {
    valid[i] = std::isfinite(measurement_[i]);
    if (!valid[i] && !coast_on_invalid) {
      has_innovation_ = false;
      return fault("non-finite measurement");
    }
  }
  // One d for every axis of this cycle, whatever set_mixing() does meanwhile.
  const double d = d_.load(std::memory_order_relaxed);
  std::array<Vector3, kMaxAxes> posterior{};
  std::array<Vector3, kMaxAxes> next_prior{};
  std::array<double, kMaxAxes> residual{};  // y_k - H x^-_k
  bool all_updated = true;
  for (std::size_t i = 0; i < axes_; ++i) {
    if (!valid[i]) {
      // Coasting (invalid_measurement: predict): x^+_k = x^-_k, x^-_{k+1} = Phi x^-_k.
      posterior[i] = prior_[i];
      next_prior[i] = model_.phi * prior_[i];
      residual[i] = 0.0;
      all_updated = false;
    } else {
      const double y = measurement_[i];
      const Vector3 prior = start_at_measurement_[i] ? Vector3(y, 0.0, 0.0) : prior_[i];
      // eq. 24 with the blended gain of eq. 25 (d = 1: 1 * K^K + 0 * K^inf == K^K bit for bit).
      const Vector3 gain = d == 1.0 ? kalman_gain_[i] : hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]);
      residual[i] = y - prior(hybrid::kPosition);
      posterior[i] = prior + gain * residual[i];
      next_prior[i] = model_.phi * posterior[i];
    }
    if (!posterior[i].allFinite() || !next_prior[i].allFinite()) {
      has_innovation_ = false;
      return fault("hybrid filter state is not finite");
    }
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    prior_[i] = next_prior[i];
    if (valid[i]) start_at_measurement_[i] = false;
    last_innovation_[i] = residual[i];
    const Vector3& out = timing_ == hybrid::OutputTiming::predicted ? next_prior[i] : posterior[i];
    outputs_.write<3>(i, out, residual[i]);  // innovation 0 on a coasting axis: the output stays finite
  }
  has_innovation_ = all_updated;
  // A new d (set_tunable()/set_mixing()) changes the steady covariance: a few 3x3 products.
  if (d != steady_cov_d_) update_steady_covariance(d);
  return StepStatus::ok;
}

StateLayout HybridH2HinfEstimator::state_layout() const {
  return estimator::axis_state_layout(measurement_elements_, 3);
}

void HybridH2HinfEstimator::export_state(double* values, double* covariance) const noexcept {
  estimator::export_axes<3>(
      axes_, [&](std::size_t i) -> const Vector3& { return prior_[i]; },
      [&](std::size_t i) -> const hybrid::Matrix3& { return steady_cov_[i]; }, values, covariance);
}

void HybridH2HinfEstimator::import_state(const double* values, const double* /*covariance*/,
                                         const std::uint8_t* present) noexcept {
  // The gains are steady: only the state is taken. An absent or non-finite element keeps the
  // block's initial value (0, as after activate()).
  for (std::size_t i = 0; i < axes_; ++i) {
    const estimator::ImportedAxis<3> in = estimator::import_axis<3>(i, axes_, values, nullptr, present, 0.0);
    prior_[i] = in.state;
    // The imported state is the prior; only a missing position still waits for a measurement.
    start_at_measurement_[i] = initialize_from_first_measurement_ && !in.position_given();
  }
}

bool HybridH2HinfEstimator::innovation(double* residual, double* variance) const noexcept {
  if (!has_innovation_) return false;
  for (std::size_t i = 0; i < axes_; ++i) {
    residual[i] = last_innovation_[i];
    variance[i] = steady_cov_[i](0, 0) + r_[i];  // H P^- H' + R
  }
  return true;
}

void HybridH2HinfEstimator::describe(Json& out) const {
  const double d = mixing();
  out["d"] = d;
  out["output"] = timing_ == hybrid::OutputTiming::predicted ? "predicted (H x^-_{k+1})" : "filtered (H x^+_k, eq. 24)";
  out["initialize_from_first_measurement"] = initialize_from_first_measurement_;
  out["invalid_measurement"] = estimator::invalid_measurement_text(invalid_measurement_);
  out["period_s"] = period_s_;
  out["phi"] = matrix_json(model_.phi);
  out["upsilon"] = vector_values(model_.upsilon);
  out["kalman_gain_source"] = kalman_injected_ ? "injected (kalman_gain)" : "designed: steady-state DARE (eqs. 26-28)";
  out["hinf_gain_source"] = hinf_injected_ ? "injected (hinf_gain)" : "designed: Simon 2001 minimax recursion";
  Json units = Json::array();
  for (const char* u : {"1", "1/s", "1/s^2"}) units.push(u);
  out["gain_units"] = std::move(units);
  Json axes = Json::array();
  for (std::size_t i = 0; i < axes_; ++i) {
    const Element& e = measurement_elements_[i];
    Json axis = Json::object();
    axis["name"] = e.name;
    axis["unit"] = e.unit;
    axis["q"] = q_[i];
    axis["q_unit"] = e.unit + "^2/s^6";
    axis["r"] = r_[i];
    axis["r_unit"] = e.unit + "^2";
    axis["kalman_gain"] = vector_values(kalman_gain_[i]);
    axis["hinf_gain"] = vector_values(hinf_gain_[i]);
    if (!hinf_injected_ && i < hinf_weights_.size()) {
      const hybrid::HinfWeights& w = hinf_weights_[i];
      Json h = Json::object();
      h["theta"] = w.theta;
      // Bisection over the Riccati recursion: computed here, not in configure(), to keep loading fast.
      const hybrid::KalmanDesign start = hybrid::design_kalman(model_, w.process_weight, w.measurement_weight);
      const double max_theta = hybrid::max_feasible_theta(model_, w, start.prior_cov);
      h["max_feasible_theta"] = std::isfinite(max_theta) ? Json(max_theta) : Json("unbounded");
      h["error_weight_diagonal"] = vector_values(w.error_weight);
      h["process_weight_w"] = w.process_weight;
      h["measurement_weight_v"] = w.measurement_weight;
      h["iterations"] = hinf_iterations_[i];
      axis["hinf_design"] = std::move(h);
    }
    axis["blended_gain"] = vector_values(hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]));
    {
      hybrid::Matrix3 cov;
      if (hybrid::blended_prior_covariance(model_, hybrid::blend(d, kalman_gain_[i], hinf_gain_[i]), q_[i], r_[i], cov)) {
        axis["steady_prior_covariance"] = matrix_json(cov);
      } else {
        axis["steady_prior_covariance"] = "no finite solution";
      }
    }
    Json sweep = Json::array();
    for (double weight : kPaperWeights) {
      const Vector3 k = hybrid::blend(weight, kalman_gain_[i], hinf_gain_[i]);
      const hybrid::PositionResponse response = hybrid::position_response(model_, k, period_s_);
      Json row = Json::object();
      row["d"] = weight;
      row["spectral_radius"] = hybrid::error_spectral_radius(model_, k);
      row["position_bandwidth_hz"] = response.bandwidth_hz;
      row["peak_gain_db"] = response.peak_db;
      row["peak_hz"] = response.peak_hz;
      sweep.push(std::move(row));
    }
    axis["mixing_sweep"] = std::move(sweep);
    axes.push(std::move(axis));
  }
  out["axes"] = std::move(axes);
  // The paper's warning on eq. 25: is every d in [0, 1] stable, not only the configured one?
  double worst = 0.0;
  double worst_d = 0.0;
  for (int k = 0; k <= 100; ++k) {
    const double weight = k / 100.0;
    const double rho = worst_spectral_radius(weight);
    if (rho > worst) {
      worst = rho;
      worst_d = weight;
    }
  }
  Json stability = Json::object();
  stability["worst_spectral_radius_d_0_to_1_step_0.01"] = worst;
  stability["at_d"] = worst_d;
  stability["every_d_stable"] = worst < 1.0;
  out["stability"] = std::move(stability);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"d", "number", "1", "mixing weight of eq. 25, K = d K^K + (1 - d) K^inf, in [0, 1]; set_mixing() at run time"},
    {"q", "number|list<number>", nullptr,
     "Q_k of eq. 27 per axis (or one for all): jerk variance [unit^2/s^6], > 0 (paper: 1e3, 1e3, 1e5, 1e2, 1e2, 1e2)"},
    {"r", "number|list<number>", nullptr, "R_k of eq. 26 per axis: measurement variance [unit^2], > 0 (paper: 1e-6)"},
    {"hinf_theta", "number|list<number>", "required unless hinf_gain",
     "H-infinity performance level theta per axis (J < 1/theta), >= 0; refused with the largest feasible value "
     "when the existence condition fails"},
    {"hinf_error_weight", "list<number>[3]", "[1, 0, 0]",
     "diagonal of S, the weight on the estimation error [position, velocity, acceleration], >= 0"},
    {"hinf_process_weight", "number|list<number>", "q", "w of the process weight W = Upsilon w Upsilon', > 0"},
    {"hinf_measurement_weight", "number|list<number>", "r", "measurement weight V, > 0"},
    {"kalman_gain", "list<number>[3|3n]", "designed",
     "inject K^K: [position, velocity 1/s, acceleration 1/s^2] for every axis, or 3 per axis (e.g. eq. 28)"},
    {"hinf_gain", "list<number>[3|3n]", "designed", "inject K^inf, same layout as kalman_gain"},
    {"output", "text", "filtered", "filtered (H x^+_k, eq. 24, what the paper's LQ uses) or predicted (H x^-_{k+1})"},
    {"initialize_from_first_measurement", "bool", "true",
     "the first measurement sets the position state (false: start from 0)"},
    {"invalid_measurement", "text", "fault",
     "fault: a non-finite measurement faults the step; predict: that axis skips its measurement update for "
     "the cycle (x^-_{k+1} = Phi x^-_k, coasting), innovation() reports no update for that cycle and the "
     "outputs stay finite"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "n <= 6 measured positions, any names and units (e.g. x, y, theta_z, z, theta_x, theta_y)"},
    {"pose", PortDirection::out, "estimated positions, same names and units as the measurement"},
    {"velocity", PortDirection::out, "<name>_dot [<unit>/s]"},
    {"acceleration", PortDirection::out, "<name>_ddot [<unit>/s^2]"},
    {"innovation", PortDirection::out, "y_k - H x^-_k, same names and units as the measurement"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::HybridH2HinfEstimator, "estimator.hybrid_h2hinf", lode::PluginKind::estimator, "0.1.0",
            "Per-axis constant-acceleration filter with a run-time blend of Kalman and H-infinity gains "
            "(Silva-Rivas & Kim 2013, eqs. 20-25)",
            lode::plugins::kParams, lode::plugins::kPorts)
