// ModelEstimator::describe(): the models, the noise, and the filter linearised at the initial
// state (off the RT thread).
#include <Eigen/Eigenvalues>
#include <array>

#include "estimator/describe_json.hpp"
#include "estimator/model_estimator.hpp"
#include "lode/sdk/math/riccati.hpp"

namespace lode::plugins::nonlinear {

using estimator::matrix_json;
using estimator::vector_values;

void ModelEstimator::describe_linearisation(Json& out) const {
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
    for (Eigen::Index i = 0; i < z.size(); ++i) poles.push(estimator::error_pole_json(z(i), dt_));
    ss["error_poles_z"] = std::move(poles);
    lin["steady_state"] = std::move(ss);
  }
  out["linearised"] = std::move(lin);
}

void ModelEstimator::describe(Json& out) const {
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
      out["process_model"] = estimator::description_of(*plant);
    }
  }
  if (measurement_) out["measurement_model"] = estimator::description_of(*measurement_);
}

}  // namespace lode::plugins::nonlinear
