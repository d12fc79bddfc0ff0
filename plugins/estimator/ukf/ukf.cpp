#include "ukf.hpp"

#include <string>

#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

void UnscentedEstimator::read_filter_params(Params& params) {
  alpha_ = params.number("alpha", 0.002);
  beta_ = params.number("beta", 2.0);
  kappa_ = params.number("kappa", 0.0);
  redraw_ = params.flag("redraw_after_prediction", false);
  compile_time_sizes_ = params.flag("compile_time_sizes", true);
}

Status UnscentedEstimator::prepare_filter(Params& params) {
  const int n = static_cast<int>(n_);
  params.check(alpha_ > 0.0 && alpha_ <= 1.0, "alpha",
               "the sigma-point spread alpha must be in (0, 1], got " + number_text(alpha_));
  params.check(beta_ >= 0.0, "beta", "beta must be >= 0 (2 is optimal for Gaussians), got " +
                                         number_text(beta_));
  params.check(n + kappa_ > 0.0, "kappa",
               "L + kappa must be > 0 (L = " + std::to_string(n) + "), got kappa = " + number_text(kappa_));
  if (!params.ok()) return Status::error("invalid parameters");
  weights_ = ukf::Weights::make(n, alpha_, beta_, kappa_);
  fixed_ = compile_time_sizes_ && n_ == 3 && m_ == 1;
  if (fixed_) {
    prepare(suspension_);
  } else {
    prepare(any_);
  }
  return Status::ok();
}

template <class S>
void UnscentedEstimator::prepare(S& sized) {
  sized.core.configure(static_cast<int>(n_), static_cast<int>(m_), weights_, ukf::Sums::about_centre, redraw_);
  sized.core.set(x0_, P0_);
  sized.Q = Q_;
  sized.R = R_;
  sized.y.setZero(static_cast<Eigen::Index>(m_));
}

void UnscentedEstimator::reset_filter() noexcept {
  if (fixed_) {
    suspension_.core.set(x_, P_);
  } else {
    any_.core.set(x_, P_);
  }
}

StepStatus UnscentedEstimator::filter_cycle(bool first) noexcept {
  return fixed_ ? cycle(suspension_, first) : cycle(any_, first);
}

template <class S>
StepStatus UnscentedEstimator::cycle(S& sized, bool first) noexcept {
  auto& core = sized.core;
  if (!core.draw()) {
    core.set(x_, P_);
    return fault("UKF: (L + lambda) P is not positive definite (Cholesky failed)");
  }
  if (!first && !core.predict(
                    [this](const double* x, std::size_t count, double* next) { propagate_points(x, count, next); },
                    sized.Q)) {
    core.set(x_, P_);
    return fault("UKF: the predicted state or covariance is not finite");
  }
  for (Eigen::Index c = 0; c < sized.y.size(); ++c) sized.y(c) = y_(c);  // no memmove call
  if (!core.update([this](const double* x, std::size_t count, double* y) { measure_points(x, count, y); },
                   sized.y, sized.R)) {
    core.set(x_, P_);
    return fault("UKF: P_yy not positive definite, or the updated state is not finite");
  }
  commit_estimate(core.x(), core.P(), core.innovation(), core.innovation_variance());
  return StepStatus::ok;
}

const nonlinear::GainMatrix& UnscentedEstimator::gain() const {
  if (fixed_) {
    gain_copy_ = suspension_.core.gain();
  } else {
    gain_copy_ = any_.core.gain();
  }
  return gain_copy_;
}

void UnscentedEstimator::describe_filter(Json& out) const {
  out["algorithm"] = "unscented Kalman filter, additive noise (eq. 20-31)";
  out["alpha"] = alpha_;
  out["beta"] = beta_;
  out["kappa"] = kappa_;
  out["lambda"] = weights_.lambda;
  out["sigma_points"] = 2 * weights_.states + 1;
  out["weight_mean_0"] = weights_.mean0;
  out["weight_cov_0"] = weights_.cov0;
  out["weight_i"] = weights_.other;
  out["sum_mean_weights"] = weights_.mean_sum();
  out["spread_sigmas"] = std::sqrt(weights_.spread());
  out["square_root"] = "lower Cholesky factor of (L + lambda) P, column i";
  out["sums"] = "about the centre point chi_0 (deviation form)";
  out["redraw_after_prediction"] = redraw_;
  out["algebra"] = fixed_ ? "sized at compile time (n = 3, m = 1)" : "generic (sizes chosen at configure)";
  out["measurement_update_points"] = redraw_ ? "redrawn around (x^-, P^-): Q_k reaches P_yy, P_xy"
                                             : "the propagated points (eq. 25, the paper's form)";
}

namespace {

constexpr ParamDoc kParams[] = {
    LODE_MODEL_ESTIMATOR_PARAM_DOCS,
    {"alpha", "number", "0.002", "sigma-point spread (eq. 21), 0 < alpha <= 1 (the paper: 0.002)"},
    {"beta", "number", "2", "prior-distribution weight (2: Gaussian), >= 0"},
    {"kappa", "number", "0", "secondary scaling, L + kappa > 0"},
    {"redraw_after_prediction", "bool", "false",
     "false: the propagated points go through h (eq. 25, the paper); true: redraw them around (x^-, P^-) "
     "so that Q_k enters P_yy and P_xy"},
    {"compile_time_sizes", "bool", "true",
     "true: a model with n = 3 states and m = 1 channel (plant.suspension with a gap) runs algebra sized at compile "
     "time, same results, faster; false: the generic code every size runs (for comparison)"},
};

constexpr PortSpec kPorts[] = {LODE_MODEL_ESTIMATOR_PORT_DOCS};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::UnscentedEstimator, "estimator.ukf", lode::PluginKind::estimator, "0.1.0",
            "Unscented Kalman filter over plugin process and measurement models, sums about the centre point",
            lode::plugins::kParams, lode::plugins::kPorts)
