#include "ekf.hpp"

#include <Eigen/Cholesky>
#include <array>
#include <string>

#include "lode/sdk/plugin.hpp"

namespace lode::plugins {

using nonlinear::ChannelMatrix;
using nonlinear::ChannelVector;
using nonlinear::GainMatrix;
using nonlinear::ObservationMatrix;
using nonlinear::StateMatrix;
using nonlinear::StateVector;

void ExtendedEstimator::read_filter_params(Params& params) {
  const std::string source = params.choice("jacobian", {"auto", "analytic", "numerical"}, std::string_view("auto"));
  jacobian_ = source == "analytic"    ? JacobianSource::analytic
              : source == "numerical" ? JacobianSource::numerical
                                      : JacobianSource::automatic;
}

Status ExtendedEstimator::prepare_filter(Params& params) {
  StateMatrix F;
  const std::array<double, nonlinear::kMaxInputs> no_input{};
  model_has_jacobian_ = analytic_process_jacobian(x0_.data(), no_input.data(), F);
  if (jacobian_ == JacobianSource::analytic && !model_has_jacobian_) {
    params.fail("jacobian", "the process model provides no analytic Jacobian (e.g. plant.suspension with "
                            "process_discretization: rk4); use auto or numerical");
    return Status::error("invalid parameters");
  }
  gain_.setZero(static_cast<Eigen::Index>(n_), static_cast<Eigen::Index>(m_));
  return Status::ok();
}

StepStatus ExtendedEstimator::filter_cycle(bool first) noexcept {
  const auto n = static_cast<Eigen::Index>(n_);
  StateVector x_prior = x_;
  StateMatrix P_prior = P_;
  if (!first) {
    // Time update about x_{k-1|k-1} with u_{k-1}.
    StateMatrix F;
    used_analytic_ = jacobian_ != JacobianSource::numerical && analytic_process_jacobian(x_.data(), u_.data(), F);
    if (!used_analytic_) {
      const StateVector scale = P_.diagonal().cwiseMax(0.0).cwiseSqrt();
      numerical_process_jacobian(x_.data(), u_.data(), scale, F);
    }
    propagate(x_.data(), x_prior.data());
    P_prior.noalias() = F * P_ * F.transpose();
    P_prior += Q_;
  }
  // Measurement update about x_{k|k-1}.
  ObservationMatrix H;
  ChannelVector y_hat(static_cast<Eigen::Index>(m_));
  measure_jacobian(x_prior.data(), y_hat.data(), H);
  ChannelMatrix S = R_;
  S.noalias() += H * P_prior * H.transpose();
  Eigen::LLT<ChannelMatrix> s_llt(S);
  if (s_llt.info() != Eigen::Success) return fault("EKF: innovation covariance H P H' + R not positive definite");
  const GainMatrix K = s_llt.solve(H * P_prior).transpose();  // P H' S^-1 (P, S symmetric)
  const ChannelVector innovation = y_ - y_hat;
  const StateVector x = x_prior + K * innovation;
  StateMatrix I_KH = StateMatrix::Identity(n, n);
  I_KH.noalias() -= K * H;
  StateMatrix P(n, n);
  P.noalias() = I_KH * P_prior * I_KH.transpose();
  P.noalias() += K * R_ * K.transpose();
  P = (0.5 * (P + P.transpose())).eval();
  if (!x.allFinite() || !P.allFinite()) return fault("EKF: the updated state or covariance is not finite");
  x_ = x;
  P_ = P;
  innovation_ = innovation;
  innovation_variance_ = S.diagonal();
  gain_ = K;
  return StepStatus::ok;
}

void ExtendedEstimator::describe_filter(Json& out) const {
  out["algorithm"] = "extended Kalman filter, additive noise, Joseph-form covariance update";
  out["jacobian"] = jacobian_ == JacobianSource::numerical ? "numerical (forced)"
                    : model_has_jacobian_                  ? "analytic (from the process model)"
                                                           : "central differences (the model has no analytic one)";
  out["difference_step"] = "eps^(1/3) max(|x_j|, sqrt(P_jj)) per state (numerical only)";
}

namespace {

constexpr ParamDoc kParams[] = {
    LODE_MODEL_ESTIMATOR_PARAM_DOCS,
    {"jacobian", "text", "auto",
     "auto (the model's analytic F if it has one, else central differences), analytic (required), numerical"},
};

constexpr PortSpec kPorts[] = {LODE_MODEL_ESTIMATOR_PORT_DOCS};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::ExtendedEstimator, "estimator.ekf", lode::PluginKind::estimator, "0.1.0",
            "Extended Kalman filter over plugin process and measurement models (analytic or numerical F)",
            lode::plugins::kParams, lode::plugins::kPorts)
