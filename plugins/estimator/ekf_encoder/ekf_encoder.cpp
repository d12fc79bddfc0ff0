#include "ekf_encoder.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <numbers>
#include <string>

#include "estimator/describe_json.hpp"
#include "estimator/position_gain.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace ekf_encoder {

// estimator::i_minus_kh() and error_poles() take the measured state to be the first.
static_assert(kPosition == 0);

namespace {

/// sum_{n >= first_order} (-1)^n c(n, 2^n) a^n / n!, the Taylor series of one bracket of
/// eq. (10); the orders below first_order cancel exactly, which is what the closed form
/// loses to rounding. Converges like (2a)^n / n!; a < kSeriesThreshold needs ~20 terms.
template <typename Coefficient>
double bracket_series(double a, int first_order, Coefficient coefficient) {
  double sum = 0.0;
  double power_over_factorial = 1.0;  // a^n / n!
  double two_to_n = 1.0;
  for (int n = 1; n <= 60; ++n) {
    power_over_factorial *= a / n;
    two_to_n *= 2.0;
    if (n < first_order) continue;
    const double sign = (n % 2 == 0) ? 1.0 : -1.0;
    const double term = sign * coefficient(static_cast<double>(n), two_to_n) * power_over_factorial;
    sum += term;
    if (n > first_order + 2 && std::abs(term) <= 1e-18 * std::abs(sum)) break;
  }
  return sum;
}

StateMatrix symmetric_from(double q11, double q12, double q13, double q22, double q23, double q33) {
  StateMatrix q;
  q << q11, q12, q13,  //
      q12, q22, q23,   //
      q13, q23, q33;
  return q;
}

}  // namespace

StateMatrix singer_transition(double alpha_rad_s, double period_s) {
  const double a = alpha_rad_s * period_s;
  // (aT - 1 + e^-aT) / a^2 written as T^2 (a - 1 + e^-a) / a^2 with a = alpha T; its series
  // sum_{n>=2} (-a)^(n-2) / n! avoids the cancellation for small a.
  double position_from_acceleration = 0.0;
  if (a < kSeriesThreshold) {
    double term = 0.5;  // n = 2
    for (int n = 2; n < 40; ++n) {
      position_from_acceleration += term;
      term *= -a / (n + 1);
    }
    position_from_acceleration *= period_s * period_s;
  } else {
    position_from_acceleration = (a - 1.0 + std::exp(-a)) / (alpha_rad_s * alpha_rad_s);
  }
  StateMatrix f;
  f << 1.0, period_s, position_from_acceleration,          //
      0.0, 1.0, -std::expm1(-a) / alpha_rad_s,             // (1 - e^-aT) / a
      0.0, 0.0, std::exp(-a);                              // eq. 9
  return f;
}

StateMatrix singer_process_noise(double alpha_rad_s, double period_s, double acceleration_variance) {
  const double a = alpha_rad_s * period_s;
  double b11, b12, b13, b22, b23;
  if (a < kSeriesThreshold) {
    // Coefficient of a^n of each bracket, from the exponential series:
    //   (10a) (4n - 2^n)/n!  from n = 5 ((aT)^5/10),  (10b) (2^n - 2 - 2n)/n! from n = 4,
    //   (10c) (2n - 2^n)/n!  from n = 3,  (10d) (4 - 2^n)/n! from n = 3,  (10e) (2^n - 2)/n!
    //   from n = 2, each times (-1)^n.
    b11 = bracket_series(a, 5, [](double n, double p) { return 4.0 * n - p; });
    b12 = bracket_series(a, 4, [](double n, double p) { return p - 2.0 - 2.0 * n; });
    b13 = bracket_series(a, 3, [](double n, double p) { return 2.0 * n - p; });
    b22 = bracket_series(a, 3, [](double /*n*/, double p) { return 4.0 - p; });
    b23 = bracket_series(a, 2, [](double /*n*/, double p) { return p - 2.0; });
  } else {
    const double e1 = std::exp(-a);
    const double e2 = std::exp(-2.0 * a);
    b11 = 1.0 - e2 + 2.0 * a + 2.0 * a * a * a / 3.0 - 2.0 * a * a - 4.0 * a * e1;
    b12 = e2 + 1.0 - 2.0 * e1 + 2.0 * a * e1 - 2.0 * a + a * a;
    b13 = 1.0 - e2 - 2.0 * a * e1;
    b22 = 4.0 * e1 - 3.0 - e2 + 2.0 * a;
    b23 = e2 + 1.0 - 2.0 * e1;
  }
  const double b33 = -std::expm1(-2.0 * a);  // 1 - e^-2aT without cancellation
  const double s = acceleration_variance;
  const double alpha2 = alpha_rad_s * alpha_rad_s;
  return symmetric_from(s * b11 / (alpha2 * alpha2), s * b12 / (alpha2 * alpha_rad_s), s * b13 / alpha2,
                        s * b22 / alpha2, s * b23 / alpha_rad_s, s * b33);
}

StateMatrix singer_process_noise_as_printed(double alpha_rad_s, double period_s,
                                            double acceleration_variance) {
  const double a = alpha_rad_s * period_s;
  const double s = acceleration_variance;
  const double e1 = std::exp(-a);
  const double e2 = std::exp(-2.0 * a);
  const double alpha2 = alpha_rad_s * alpha_rad_s;
  const double alpha3 = alpha2 * alpha_rad_s;
  const double alpha4 = alpha2 * alpha2;
  const double q11 = s / alpha4 * (1.0 - e2 + 2.0 * a + 2.0 * a * a * a / 3.0 - 2.0 * a * a - 4.0 * a * e1);  // 10a
  const double q12 = s / alpha3 * (e2 + 1.0 - 2.0 * e1 + 2.0 * a * e1 - 2.0 * a + a * a);            // 10b
  const double q13 = s / alpha2 * (1.0 - e2 - 2.0 * a * e1);                                       // 10c
  const double q22 = s / alpha2 * (4.0 * e1 - 3.0 - e2 + 2.0 * a);                                  // 10d
  const double q23 = s / alpha_rad_s * (e2 + 1.0 - 2.0 * e1);                                      // 10e
  const double q33 = s * (1.0 - e2);                                                               // 10f
  return symmetric_from(q11, q12, q13, q22, q23, q33);
}

SteadyState steady_state(const StateMatrix& transition, const StateMatrix& process_noise,
                         double position_variance, const StateMatrix& initial_cov) {
  SteadyState result;
  StateMatrix prior = initial_cov;
  StateVector previous_std = StateVector::Zero();
  for (int iteration = 1; iteration <= kRiccatiMaxIterations; ++iteration) {
    // eq. 15-16 with a scalar position measurement of variance r_eq (Joseph form), then 13.
    const StateVector gain = prior.col(kPosition) / (prior(kPosition, kPosition) + position_variance);
    const StateMatrix i_minus_kh = estimator::i_minus_kh(gain);
    StateMatrix posterior = i_minus_kh * prior * i_minus_kh.transpose() +
                            (gain * position_variance) * gain.transpose();
    posterior = 0.5 * (posterior + posterior.transpose()).eval();
    StateMatrix next = transition * posterior * transition.transpose() + process_noise;
    next = 0.5 * (next + next.transpose()).eval();
    result.prior_cov = prior;
    result.posterior_cov = posterior;
    result.gain = gain;
    result.iterations = iteration;
    if (!next.allFinite()) break;
    const StateVector std = posterior.diagonal().cwiseMax(0.0).cwiseSqrt();
    if (iteration > 1 && estimator::settled(std, previous_std, kRiccatiTolerance)) {
      result.converged = true;
      break;
    }
    previous_std = std;
    prior = next;
  }
  result.poles = estimator::error_poles(transition, result.gain);  // a-priori error e(k+1|k)
  return result;
}

void Filter::configure(const StateMatrix& transition, const StateMatrix& process_noise,
                       const std::vector<double>& noise_variance, const StateVector& initial_std,
                       bool compile_time_sizes) {
  channels_ = noise_variance.size();
  f_ = transition;
  q_ = process_noise;
  const auto m = static_cast<Eigen::Index>(channels_);
  r_ = ChannelMatrix::Zero(m, m);
  for (Eigen::Index i = 0; i < m; ++i) r_(i, i) = noise_variance[static_cast<std::size_t>(i)];
  sized_ = compile_time_sizes && channels_ == static_cast<std::size_t>(kSizedChannels);
  if (sized_) sized_r_ = r_;
  p0_ = initial_std.cwiseProduct(initial_std).asDiagonal();
  innovation_ = ChannelVector::Zero(m);
  reset(0.0);
}

void Filter::reset(double position_m) noexcept {
  x_ = StateVector::Zero();
  x_(kPosition) = position_m;
  p_ = p0_;
  innovation_.setZero();
}

void Filter::predict() noexcept {
  x_ = f_ * x_;                                 // eq. 12
  p_ = f_ * p_ * f_.transpose() + q_;           // eq. 13
  p_ = 0.5 * (p_ + p_.transpose()).eval();
}

bool Filter::update(const double* measured, const double* predicted, const double* slope) noexcept {
  return sized_ ? update_with<SizedChannelVector>(sized_r_, measured, predicted, slope)
                : update_with<ChannelVector>(r_, measured, predicted, slope);
}

template <typename Vector, typename Matrix>
bool Filter::update_with(const Matrix& r, const double* measured, const double* predicted,
                         const double* slope) noexcept {
  const auto m = static_cast<Eigen::Index>(channels_);
  Vector h;
  Vector innovation;
  if constexpr (Vector::SizeAtCompileTime == Eigen::Dynamic) {
    h.resize(m);
    innovation.resize(m);
  }
  for (Eigen::Index i = 0; i < m; ++i) {
    h(i) = slope[i];
    innovation(i) = measured[i] - predicted[i];  // z - h(x(k+1|k)), eq. 14
  }
  // S = H P H' + R with H = [h 0 0] (eq. 11, 15).
  Matrix s = r;
  s.noalias() += (p_(kPosition, kPosition) * h) * h.transpose();
  const Eigen::LLT<Matrix> llt(s);
  if (llt.info() != Eigen::Success) return false;
  const Vector w = llt.solve(h);  // S^-1 h, so K = P e1 w'
  const double wh = w.dot(h);
  const double wrw = w.dot(r * w);
  const double wv = w.dot(innovation);

  const StateVector p_col = p_.col(kPosition);
  const StateVector x_next = x_ + p_col * wv;  // eq. 14
  // eq. 16 (Joseph): K H = (P e1 w'h) e1' and K R K' = (w'Rw) P e1 e1' P.
  const StateMatrix i_minus_kh = estimator::i_minus_kh(p_col * wh);
  StateMatrix p_next = i_minus_kh * p_ * i_minus_kh.transpose() + (wrw * p_col) * p_col.transpose();
  p_next = 0.5 * (p_next + p_next.transpose()).eval();

  if (!x_next.allFinite() || !p_next.allFinite() || !(p_next(kPosition, kPosition) > 0.0)) return false;
  x_ = x_next;
  p_ = p_next;
  innovation_ = innovation;
  return true;
}

}  // namespace ekf_encoder

namespace {

using ekf_encoder::StateMatrix;
using ekf_encoder::StateVector;
using estimator::matrix_json;

std::vector<double> sqrt_diagonal(const StateMatrix& p) {
  return {std::sqrt(p(0, 0)), std::sqrt(p(1, 1)), std::sqrt(p(2, 2))};
}

constexpr double kDefaultAlpha = 200.0 * std::numbers::pi;  // Table 1: 200 pi rad/s

}  // namespace

Status EkfEncoder::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();

  model_name_ = params.text("model");
  if (!model_name_.empty()) model_ = ctx.measurement_model("model");  // nullptr: the context said why
  alpha_rad_s_ = params.number("acceleration_pole_rad_s", kDefaultAlpha);
  acceleration_variance_ = params.number("acceleration_variance_m2_s4", 1e-5);
  noise_std_v_ = params.numbers("noise_std_v", std::vector<double>{8e-3});
  initial_std_ << params.number("initial_position_std_m", 4e-8),
      params.number("initial_velocity_std_m_s", 1e-4), params.number("initial_acceleration_std_m_s2", 1e-2);
  initial_position_m_ = params.number("initial_position_m", 0.0);
  compile_time_sizes_ = params.flag("compile_time_sizes", true);

  params.check(std::isfinite(alpha_rad_s_) && alpha_rad_s_ > 0.0, "acceleration_pole_rad_s",
               "alpha must be > 0 rad/s (Table 1: 200 pi), got " + number_text(alpha_rad_s_));
  params.check(std::isfinite(acceleration_variance_) && acceleration_variance_ >= 0.0,
               "acceleration_variance_m2_s4",
               "sigma_m^2 must be >= 0 (Table 1: 1e-5), got " + number_text(acceleration_variance_));
  const char* std_keys[] = {"initial_position_std_m", "initial_velocity_std_m_s",
                            "initial_acceleration_std_m_s2"};
  for (int i = 0; i < ekf_encoder::kStateSize; ++i) {
    params.check(std::isfinite(initial_std_(i)) && initial_std_(i) > 0.0, std_keys[i],
                 "P(0) must be positive definite: give a std > 0, got " + number_text(initial_std_(i)));
  }
  params.check(std::isfinite(initial_position_m_), "initial_position_m", "must be finite");

  // The measurement model fixes the channels; it must depend on one position in metres.
  Elements channels;
  if (model_) {
    const Elements& state = model_->state_elements();
    if (state.size() != 1 || canonical_unit(state[0].unit) != "m") {
      params.fail("model", "model '" + model_name_ +
                               "' must depend on exactly one state element in m (the position); it has " +
                               std::to_string(state.size()));
    }
    channels = model_->channels();
    if (channels.empty() || channels.size() > ekf_encoder::kMaxChannels) {
      params.fail("model", "model '" + model_name_ + "' must have 1 to " +
                               std::to_string(ekf_encoder::kMaxChannels) + " channels, has " +
                               std::to_string(channels.size()));
      channels.clear();
    }
  }
  channel_count_ = channels.size();
  if (channel_count_ > 0) {
    if (noise_std_v_.size() == 1) noise_std_v_.assign(channel_count_, noise_std_v_.front());
    if (noise_std_v_.size() != channel_count_) {
      params.fail("noise_std_v", "expected one number or " + std::to_string(channel_count_) +
                                     " (one per channel of '" + model_name_ + "'), got " +
                                     std::to_string(noise_std_v_.size()));
    }
  }
  for (double s : noise_std_v_) {
    if (!(s > 0.0) || !std::isfinite(s)) {
      params.fail("noise_std_v", "R must be positive definite: every std must be > 0 V, got " + number_text(s));
    }
  }

  ctx.declare_input(signals_, "signals", channels);
  ctx.declare_input(initial_, "initial", {}, false);
  if (const Elements* initial_source = ctx.input_source("initial")) {
    if (initial_source->empty() || !units_compatible((*initial_source)[0].unit, "m")) {
      params.fail("inputs", "input 'initial' must start with a position in m (e.g. arctan.estimate)");
    }
  }
  ctx.declare_output(estimate_, "estimate", {{"x", "m"}, {"v", "m/s"}});
  ctx.declare_output(acceleration_, "acceleration", {{"a", "m/s^2"}});
  ctx.declare_output(std_, "std", {{"x_std", "m"}, {"v_std", "m/s"}, {"a_std", "m/s^2"}});
  Elements innovation = channels;
  ctx.declare_output(innovation_, "innovation", innovation);

  if (!params.ok()) return Status::error("invalid parameters");
  if (!model_) return Status::error("measurement model '" + model_name_ + "' is not available (see above)");

  transition_ = ekf_encoder::singer_transition(alpha_rad_s_, period_s_);
  process_noise_ = ekf_encoder::singer_process_noise(alpha_rad_s_, period_s_, acceleration_variance_);
  std::vector<double> variance;
  for (double s : noise_std_v_) variance.push_back(s * s);
  filter_.configure(transition_, process_noise_, variance, initial_std_, compile_time_sizes_);
  return Status::ok();
}

Status EkfEncoder::activate() {
  filter_.reset(initial_position_m_);
  first_cycle_ = true;
  write_outputs();
  return Status::ok();
}

StepStatus EkfEncoder::step(const Tick& /*tick*/) noexcept {
  for (std::size_t c = 0; c < channel_count_; ++c) {
    if (!std::isfinite(signals_[c])) return fault("non-finite encoder signal");
  }
  if (first_cycle_) {
    // x(0) = [coarse position of the first sample, 0, 0], P(0) = P0 (assumed: not in the paper).
    const double position_m = initial_.connected() ? initial_[0] : initial_position_m_;
    if (!std::isfinite(position_m)) return fault("non-finite initial position");
    filter_.reset(position_m);
  } else {
    filter_.predict();  // eq. 12, 13
  }
  const double position_m = filter_.state()(ekf_encoder::kPosition);
  model_->jacobian(&position_m, predicted_.data(), slope_.data());  // h and eq. 11 at x(k+1|k)
  if (!filter_.update(signals_.data(), predicted_.data(), slope_.data())) {
    return fault("EKF update: S not positive definite or non-finite state");
  }
  first_cycle_ = false;
  write_outputs();
  return StepStatus::ok;
}

void EkfEncoder::write_outputs() noexcept {
  const StateVector& x = filter_.state();
  const StateMatrix& p = filter_.covariance();
  estimate_[0] = x(ekf_encoder::kPosition);
  estimate_[1] = x(ekf_encoder::kVelocity);
  acceleration_[0] = x(ekf_encoder::kAcceleration);
  for (int i = 0; i < ekf_encoder::kStateSize; ++i) std_[static_cast<std::size_t>(i)] = std::sqrt(p(i, i));
  for (std::size_t c = 0; c < channel_count_; ++c) {
    innovation_[c] = filter_.innovation()(static_cast<Eigen::Index>(c));
  }
}

void EkfEncoder::describe(Json& out) const {
  out["model"] = model_name_;
  if (model_) out["measurement_model"] = estimator::description_of(*model_);
  out["period_s"] = period_s_;
  out["algebra"] = filter_.fixed_size() ? "sized at compile time (2 channels)" : "generic (sizes chosen at configure)";
  out["acceleration_pole_rad_s"] = alpha_rad_s_;
  out["acceleration_variance_m2_s4"] = acceleration_variance_;
  out["alpha_T"] = alpha_rad_s_ * period_s_;
  out["process_model"] = "Singer, x = [x, v, a], F = e^{AT} (eq. 9), Q_d eq. 10 as printed";
  out["transition_F"] = matrix_json(transition_);
  out["process_noise_Qd"] = matrix_json(process_noise_);
  out["process_noise_Qd_method"] =
      alpha_rad_s_ * period_s_ < ekf_encoder::kSeriesThreshold ? "Taylor series of each bracket (alpha T < 0.5)"
                                                               : "closed form (10a-f)";
  // The printed closed form evaluated literally, and how far rounding takes it from the
  // series (~8 significant digits left at 20 kHz, ~4 at 100 kHz).
  const StateMatrix printed =
      ekf_encoder::singer_process_noise_as_printed(alpha_rad_s_, period_s_, acceleration_variance_);
  out["process_noise_Qd_as_printed"] = matrix_json(printed);
  double worst = 0.0;
  for (int i = 0; i < ekf_encoder::kStateSize; ++i)
    for (int j = 0; j < ekf_encoder::kStateSize; ++j)
      if (process_noise_(i, j) != 0.0)
        worst = std::max(worst, std::abs(printed(i, j) - process_noise_(i, j)) / std::abs(process_noise_(i, j)));
  out["as_printed_max_relative_difference"] = worst;
  out["noise_std_v"] = noise_std_v_;
  out["initial_std"] = std::vector<double>{initial_std_(0), initial_std_(1), initial_std_(2)};
  out["initial_std_units"] = "m, m/s, m/s^2";
  out["initial_position_m"] = initial_position_m_;
  out["covariance_update"] = "Joseph form (eq. 16), symmetrised";

  if (!model_) return;
  // Steady state: all channels act like one position measurement of variance
  // r_eq = 1 / sum(h_i^2 / r_i) (evaluated at initial_position_m; phase-independent for the
  // ideal sin/cos model with equal channel noise).
  std::array<double, ekf_encoder::kMaxChannels> y{};
  std::array<double, ekf_encoder::kMaxChannels> h{};
  model_->jacobian(&initial_position_m_, y.data(), h.data());
  double information = 0.0;
  for (std::size_t c = 0; c < channel_count_; ++c) information += h[c] * h[c] / (noise_std_v_[c] * noise_std_v_[c]);
  Json steady = Json::object();
  if (!(information > 0.0)) {
    steady["note"] = "no position information at initial_position_m (dh/dx = 0)";
    out["steady_state"] = std::move(steady);
    return;
  }
  const double r_eq = 1.0 / information;
  const StateMatrix p0 = initial_std_.cwiseProduct(initial_std_).asDiagonal();
  const ekf_encoder::SteadyState ss = ekf_encoder::steady_state(transition_, process_noise_, r_eq, p0);
  steady["equivalent_position_std_m"] = std::sqrt(r_eq);
  steady["converged"] = ss.converged;
  steady["iterations"] = ss.iterations;
  steady["posterior_std"] = sqrt_diagonal(ss.posterior_cov);  // Fig. 6 compares these
  steady["prior_std"] = sqrt_diagonal(ss.prior_cov);
  steady["std_units"] = "m, m/s, m/s^2";
  steady["posterior_covariance"] = matrix_json(ss.posterior_cov);
  steady["gain"] = std::vector<double>{ss.gain(0), ss.gain(1), ss.gain(2)};
  steady["gain_units"] = "1, 1/s, 1/s^2 (per metre of position innovation)";
  steady["error_poles_z"] = estimator::error_poles_json(ss.poles, period_s_, estimator::PoleRate::hz);
  out["steady_state"] = std::move(steady);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"model", "text", nullptr,
     "measurement model in `models:` (sensor.sincos_encoder): one state element x [m], 1-4 channels [V]"},
    {"acceleration_pole_rad_s", "number", "628.3185307 (200 pi)", "Singer acceleration pole alpha (Table 1), > 0"},
    {"acceleration_variance_m2_s4", "number", "1e-5",
     "sigma_m^2 of eq. 10 as printed (the steady-state acceleration variance, see README), >= 0"},
    {"noise_std_v", "number|list<number>", "8e-3", "measurement noise std per channel [V]: R = diag(std^2)"},
    {"initial_position_std_m", "number", "4e-8", "sqrt P(0)_11 [m] (pitch/100; the paper gives no P(0))"},
    {"initial_velocity_std_m_s", "number", "1e-4", "sqrt P(0)_22 [m/s]"},
    {"initial_acceleration_std_m_s2", "number", "1e-2", "sqrt P(0)_33 [m/s^2]"},
    {"initial_position_m", "number", "0",
     "x(0) when the `initial` input is not connected [m]; also where describe() evaluates the steady state"},
    {"compile_time_sizes", "bool", "true",
     "true: a 2-channel model (sin, cos) runs the update sized at compile time (same results); false: the generic code"},
};

constexpr PortSpec kPorts[] = {
    {"signals", PortDirection::in, "the model's channels [V] (e.g. io.sim signals: sin, cos)"},
    {"initial", PortDirection::in, "optional: element 0 is the coarse position [m] used at the first sample (e.g. arctan.estimate)"},
    {"estimate", PortDirection::out, "x [m], v [m/s]: a-posteriori x(k|k)"},
    {"acceleration", PortDirection::out, "a [m/s^2]"},
    {"std", PortDirection::out, "x_std [m], v_std [m/s], a_std [m/s^2]: sqrt(diag P(k|k))"},
    {"innovation", PortDirection::out, "z - h(x(k|k-1)) per channel [V]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::EkfEncoder, "estimator.ekf_encoder", lode::PluginKind::estimator, "0.1.0",
            "3-state Singer-model EKF decoding sin/cos encoder signals into absolute position, velocity and "
            "acceleration (Zimmerman 2006 eq. 6-16)",
            lode::plugins::kParams, lode::plugins::kPorts)
