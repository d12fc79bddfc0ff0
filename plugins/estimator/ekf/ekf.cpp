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
  measures_first_state_only_ = measurement_reads_first_state_only();
  if (fixed_) {
    q_sized_ = Q_;
    r_sized_ = R_;
  }
  return Status::ok();
}

StepStatus ExtendedEstimator::filter_cycle(bool first) noexcept {
  if (!fixed_) return cycle<Eigen::Dynamic, Eigen::Dynamic, false>(first);
  return measures_first_state_only_ ? cycle<3, 1, true>(first) : cycle<3, 1, false>(first);
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

template <int States, int Channels, bool FirstStateOnly>
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
  // Q_k and R in storage of the cycle's own sizes, so that no capacity-sized operand enters
  // the sized products.
  const auto& Q = [&]() -> const auto& {
    if constexpr (sized) {
      return q_sized_;
    } else {
      return Q_;
    }
  }();
  const auto& R = [&]() -> const auto& {
    if constexpr (sized) {
      return r_sized_;
    } else {
      return R_;
    }
  }();
  Vector x_post;
  Matrix P_prior;
  if constexpr (sized) {  // element by element: Eigen's copy from capacity-sized storage calls memmove
    for (int i = 0; i < States; ++i) x_post(i) = x_.data()[i];
    for (int i = 0; i < States * States; ++i) P_prior.data()[i] = P_.data()[i];
  } else {
    x_post = x_;
    P_prior = P_;
  }
  Vector x_prior = x_post;
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
    P_prior += Q;
  }
  // Measurement update about x_{k|k-1}.
  Observation H;
  MVector y_hat;
  y_hat.resize(m);
  measure_jacobian_into(x_prior.data(), u_.data(), y_hat.data(), H);
  Observation H_P;
  MMatrix S = R;
  if constexpr (FirstStateOnly) {
    // H = [h 0 ... 0]: the products' terms in H's zero columns are signed zeros added to
    // sums that start at +0, which leave them as they are (P is finite here, or the update
    // faults either way), so they are left out.
#pragma GCC unroll 4
    for (int j = 0; j < States; ++j) H_P(0, j) = 0.0 + H(0, 0) * P_prior(0, j);
    S(0, 0) += 0.0 + H_P(0, 0) * H(0, 0);
  } else {
    H_P = product(H, P_prior);
    S += product_transposed(H_P, H);
  }
  if (m == 1) {
    // One channel, sized or not (the same operations, so the same bits): S is a number,
    // K = P^- H' / S (a division per state) and P = P^- - K (H P^-), its upper triangle
    // mirrored, so P is symmetric by construction and positive definite when S > 0. Two 3 x 3
    // products and a symmetrisation cheaper than the Joseph form, equal to it to rounding.
    const double s = S(0, 0);
    if (!(s > 0.0)) return fault("EKF: innovation covariance H P H' + R not positive definite");
    const int N = sized ? States : static_cast<int>(n);
    Gain K;
    Vector x;
    Matrix P;
    MVector innovation;
    K.resize(n, 1);
    x.resize(n);
    P.resize(n, n);
    innovation.resize(1);
    innovation(0) = y_(0) - y_hat(0);
    bool finite = true;
#pragma GCC unroll 4
    for (int j = 0; j < N; ++j) {
      K(j, 0) = H_P(0, j) / s;
      x(j) = x_prior(j) + K(j, 0) * innovation(0);
      finite &= std::isfinite(x(j));
    }
#pragma GCC unroll 4
    for (int k = 0; k < N; ++k) {
#pragma GCC unroll 4
      for (int j = 0; j <= k; ++j) {
        const double v = P_prior(j, k) - K(j, 0) * H_P(0, k);
        P(j, k) = v;
        P(k, j) = v;
        finite &= std::isfinite(v);
      }
    }
    if (!finite) return fault("EKF: the updated state or covariance is not finite");
    commit_estimate(x, P, innovation, S.diagonal());
    gain_ = K;
    return StepStatus::ok;
  }
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
  Matrix P;
  if constexpr (FirstStateOnly) {
    // I - K H differs from I in its first column alone (I - (0 + K_i 0) = I exactly).
#pragma GCC unroll 4
    for (int i = 0; i < States; ++i) I_KH(i, 0) -= 0.0 + K(i, 0) * H(0, 0);
    constexpr std::array<bool, States> unit = [] {
      std::array<bool, States> u{};
      for (int k = 1; k < States; ++k) u[static_cast<std::size_t>(k)] = true;
      return u;
    }();
    joseph_products<States>(I_KH.data(), P_prior.data(), unit.data(), P.data());
  } else if constexpr (sized) {
    I_KH -= product(K, H);
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
    I_KH -= product(K, H);
    const Matrix I_KH_P = product(I_KH, P_prior);
    P = product_transposed(I_KH_P, I_KH);
  }
  const Gain K_R = product(K, MMatrix(R));
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
  out["algorithm"] = m_ == 1 ? "extended Kalman filter, additive noise, P = P^- - K H P^- (one channel)"
                            : "extended Kalman filter, additive noise, Joseph-form covariance update";
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
