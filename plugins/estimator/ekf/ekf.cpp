#include "ekf.hpp"

#include <Eigen/Cholesky>
#include <array>
#include <cmath>
#include <string>
#include <type_traits>

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
  compile_time_sizes_ = params.flag("compile_time_sizes", true);
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
  fixed_ = compile_time_sizes_ && n_ == 3 && m_ == 1;
  return Status::ok();
}

StepStatus ExtendedEstimator::filter_cycle(bool first) noexcept {
  return fixed_ ? cycle<3, 1>(first) : cycle<Eigen::Dynamic, Eigen::Dynamic>(first);
}

namespace {

/// R x C (either Eigen::Dynamic) with the block's capacity; a single row stored row-major, as
/// Eigen requires of a fixed row vector.
template <int R, int C, int MaxR, int MaxC>
using Storage = Eigen::Matrix<double, R, C, (R == 1 && C != 1) ? Eigen::RowMajor : Eigen::ColMajor,
                              R == Eigen::Dynamic ? MaxR : R, C == Eigen::Dynamic ? MaxC : C>;

/// r = a b (or a b' when TransposeB), each coefficient summed over k in order from k = 0: the
/// order Eigen's product of capacity-sized (dynamic) matrices takes. Its fixed-size product
/// of a 3-long inner dimension sums as a tree, a0 b0 + (a1 b1 + a2 b2), which changes the last
/// bit; this keeps a sized instance bit-identical to the dynamic one. a is R x K, b K x C (C x K
/// transposed), all stored column by column (a single row or column is the same either way).
/// Forced inline: a cycle makes eight of these products of at most 27 multiplications, and
/// out of line each went through memory and a call.
template <int R, int K, int C, bool TransposeB>
[[gnu::always_inline]] inline void sequential_product(const double* a, const double* b, double* r) noexcept {
  // Column j of r accumulates a's columns in k order: each coefficient's sum keeps its order
  // and the rows of a column are independent, so they can share vector instructions.
#pragma GCC unroll 4
  for (int j = 0; j < C; ++j) {
    double sum[R];
#pragma GCC unroll 4
    for (int i = 0; i < R; ++i) sum[i] = 0.0;
#pragma GCC unroll 4
    for (int k = 0; k < K; ++k) {
      const double factor = TransposeB ? b[j + k * C] : b[k + j * K];
#pragma GCC unroll 4
      for (int i = 0; i < R; ++i) sum[i] += a[i + k * R] * factor;
    }
#pragma GCC unroll 4
    for (int i = 0; i < R; ++i) r[i + j * R] = sum[i];
  }
}

/// r = (A P) A' for N x N A, P (column-major) with the sums of sequential_product, where
/// unit[k] says that column k of A is exactly e_k. Such a column's terms are A(i,k) P(k,j) =
/// P(k,j) for i = k and a signed zero otherwise, and a signed zero added to a sum that starts
/// at +0 leaves it as it was, so they are added or left out without computing them: the same
/// bits for finite operands. A non-finite P or A makes r non-finite either way (each P(k,j)
/// reaches r(., j) through a unit column or a product), so the step faults as before.
template <int N>
[[gnu::always_inline]] inline void joseph_products(const double* a, const double* p, const bool* unit,
                                                   double* r) noexcept {
  double ap[N * N];  // A P
#pragma GCC unroll 4
  for (int j = 0; j < N; ++j) {
    double sum[N];
#pragma GCC unroll 4
    for (int i = 0; i < N; ++i) sum[i] = 0.0;
#pragma GCC unroll 4
    for (int k = 0; k < N; ++k) {
      const double factor = p[k + j * N];
      if (unit[k]) {
        sum[k] += factor;
      } else {
#pragma GCC unroll 4
        for (int i = 0; i < N; ++i) sum[i] += a[i + k * N] * factor;
      }
    }
#pragma GCC unroll 4
    for (int i = 0; i < N; ++i) ap[i + j * N] = sum[i];
  }
  // (A P) A': r(i, j) = sum_k (A P)(i, k) A(j, k).
#pragma GCC unroll 4
  for (int j = 0; j < N; ++j) {
    double sum[N];
#pragma GCC unroll 4
    for (int i = 0; i < N; ++i) sum[i] = 0.0;
#pragma GCC unroll 4
    for (int k = 0; k < N; ++k) {
      if (unit[k]) {
        if (k != j) continue;
#pragma GCC unroll 4
        for (int i = 0; i < N; ++i) sum[i] += ap[i + k * N];
      } else {
        const double factor = a[j + k * N];
#pragma GCC unroll 4
        for (int i = 0; i < N; ++i) sum[i] += ap[i + k * N] * factor;
      }
    }
#pragma GCC unroll 4
    for (int i = 0; i < N; ++i) r[i + j * N] = sum[i];
  }
}

}  // namespace

template <int States, int Channels>
StepStatus ExtendedEstimator::cycle(bool first) noexcept {
  constexpr int kN = nonlinear::kMaxStates;
  constexpr int kM = nonlinear::kMaxChannels;
  using Vector = Storage<States, 1, kN, 1>;
  using Matrix = Storage<States, States, kN, kN>;
  using MVector = Storage<Channels, 1, kM, 1>;
  using MMatrix = Storage<Channels, Channels, kM, kM>;
  using Gain = Storage<States, Channels, kN, kM>;
  using Observation = Storage<Channels, States, kM, kN>;
  const auto n = static_cast<Eigen::Index>(n_);
  const auto m = static_cast<Eigen::Index>(m_);
  // Products: Eigen's own for the dynamic sizes, summed in its order for the sized ones.
  constexpr bool sized = States != Eigen::Dynamic;
  const auto multiply = [](const auto& a, const auto& b, auto transpose_b) {
    using A = std::decay_t<decltype(a)>;
    using B = std::decay_t<decltype(b)>;
    constexpr bool transposed = decltype(transpose_b)::value;
    constexpr int rows = A::RowsAtCompileTime;
    constexpr int cols = transposed ? B::RowsAtCompileTime : B::ColsAtCompileTime;
    using Result = Storage<rows, cols, kN, kN>;
    Result r;
    if constexpr (sized) {
      sequential_product<rows, A::ColsAtCompileTime, cols, transposed>(a.data(), b.data(), r.data());
    } else if constexpr (transposed) {
      r.resize(a.rows(), b.rows());
      r.noalias() = a * b.transpose();
    } else {
      r.resize(a.rows(), b.cols());
      r.noalias() = a * b;
    }
    return r;
  };
  const auto product = [&](const auto& a, const auto& b) { return multiply(a, b, std::false_type{}); };
  const auto product_transposed = [&](const auto& a, const auto& b) { return multiply(a, b, std::true_type{}); };
  const Vector x_post = x_;
  Vector x_prior = x_post;
  Matrix P_prior = P_;
  if (!first) {
    // Time update about x_{k-1|k-1} with u_{k-1}.
    const Matrix P_post = P_prior;
    Matrix F;
    used_analytic_ = jacobian_ != JacobianSource::numerical && analytic_process_jacobian_into(x_post.data(), u_.data(), F);
    if (!used_analytic_) {
      const Vector scale = P_post.diagonal().cwiseMax(0.0).cwiseSqrt();
      numerical_process_jacobian_into(x_post.data(), u_.data(), scale, F);
    }
    propagate(x_post.data(), x_prior.data());
    const Matrix F_P = product(F, P_post);
    P_prior = product_transposed(F_P, F);
    P_prior += Q_;
  }
  // Measurement update about x_{k|k-1}.
  Observation H;
  MVector y_hat;
  y_hat.resize(m);
  measure_jacobian_into(x_prior.data(), u_.data(), y_hat.data(), H);
  const Observation H_P = product(H, P_prior);
  MMatrix S = R_;
  S += product_transposed(H_P, H);
  Gain K;
  if constexpr (Channels == 1) {
    // S is a number: its Cholesky factor is sqrt(S) and the two triangular solves scale by
    // its reciprocal, as Eigen's solve does (a plain division by S would round differently).
    if (!(S(0, 0) > 0.0) && !std::isnan(S(0, 0))) {
      return fault("EKF: innovation covariance H P H' + R not positive definite");
    }
    const double inverse_root = 1.0 / std::sqrt(S(0, 0));
    K = (H_P.transpose() * inverse_root) * inverse_root;
  } else {
    Eigen::LLT<MMatrix> s_llt(S);
    if (s_llt.info() != Eigen::Success) return fault("EKF: innovation covariance H P H' + R not positive definite");
    K = s_llt.solve(H_P).transpose();  // P H' S^-1 (P, S symmetric)
  }
  const MVector innovation = MVector(y_) - y_hat;
  const Vector x = x_prior + product(K, innovation);
  Matrix I_KH = Matrix::Identity(n, n);
  I_KH -= product(K, H);
  Matrix P;
  if constexpr (sized) {
    // A column of H that is exactly zero (a state the measurement does not depend on: the
    // suspension's velocity and current) makes that column of I - K H exactly e_k.
    std::array<bool, States> unit;
#pragma GCC unroll 4
    for (int k = 0; k < States; ++k) {
      bool zero = true;
#pragma GCC unroll 4
      for (int c = 0; c < Channels; ++c) zero = zero && H(c, k) == 0.0;
      unit[k] = zero;
    }
    joseph_products<States>(I_KH.data(), P_prior.data(), unit.data(), P.data());
  } else {
    const Matrix I_KH_P = product(I_KH, P_prior);
    P = product_transposed(I_KH_P, I_KH);
  }
  const Gain K_R = product(K, MMatrix(R_));
  P += product_transposed(K_R, K);
  P = (0.5 * (P + P.transpose())).eval();
  bool finite = true;
  if constexpr (sized) {  // element by element: allFinite() is an out-of-line call per matrix
#pragma GCC unroll 4
    for (int i = 0; i < States; ++i) finite &= std::isfinite(x(i));
#pragma GCC unroll 9
    for (int i = 0; i < States * States; ++i) finite &= std::isfinite(P.data()[i]);
  } else {
    finite = x.allFinite() && P.allFinite();
  }
  if (!finite) return fault("EKF: the updated state or covariance is not finite");
  commit_estimate(x, P, innovation, S.diagonal());
  gain_ = K;
  return StepStatus::ok;
}

void ExtendedEstimator::describe_filter(Json& out) const {
  out["algorithm"] = "extended Kalman filter, additive noise, Joseph-form covariance update";
  out["jacobian"] = jacobian_ == JacobianSource::numerical ? "numerical (forced)"
                    : model_has_jacobian_                  ? "analytic (from the process model)"
                                                           : "central differences (the model has no analytic one)";
  out["difference_step"] = "eps^(1/3) max(|x_j|, sqrt(P_jj)) per state (numerical only)";
  out["algebra"] = fixed_ ? "sized at compile time (n = 3, m = 1)" : "generic (sizes chosen at configure)";
}

namespace {

constexpr ParamDoc kParams[] = {
    LODE_MODEL_ESTIMATOR_PARAM_DOCS,
    {"jacobian", "text", "auto",
     "auto (the model's analytic F if it has one, else central differences), analytic (required), numerical"},
    {"compile_time_sizes", "bool", "true",
     "true: a model with n = 3 states and m = 1 channel (plant.suspension with a gap) runs algebra sized at compile "
     "time, same results, faster; false: the generic code every size runs (for comparison)"},
};

constexpr PortSpec kPorts[] = {LODE_MODEL_ESTIMATOR_PORT_DOCS};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::ExtendedEstimator, "estimator.ekf", lode::PluginKind::estimator, "0.1.0",
            "Extended Kalman filter over plugin process and measurement models (analytic or numerical F)",
            lode::plugins::kParams, lode::plugins::kPorts)
