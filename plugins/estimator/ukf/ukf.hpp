// estimator.ukf: unscented Kalman filter over a plugin process model and a plugin measurement
// model, additive noise (Sensors 2016, 16, 1504, eq. 17-31).
//
// @system
// name: estimator.ukf
// input_ports:
//   measurement: >= m elements; the measurement model's channels by name  # e.g. hall_direct.gap: gap [m]
//   input:       >= nu elements; the process inputs by name (u_{k-1})      # e.g. stage.truth: coil_voltage [V]
// output_ports:
//   state:      n, the process state elements       # x_{k|k}, e.g. gap [m], velocity [m/s], current [A]
//   std:        n, same names and units              # sqrt(diag P_{k|k})
//   innovation: m, the measurement channels          # y_k - y^_{k|k-1}
// @endsystem
//
// Sigma points and weights (eq. 20-21), L = n states, lambda = alpha^2 (L + kappa) - L:
//   chi_0 = x,  chi_i = x + (sqrt((L+lambda) P))_i,  chi_{L+i} = x - (sqrt((L+lambda) P))_i
//   W0m = lambda/(L+lambda),  W0c = W0m + 1 - alpha^2 + beta,  Wi = 1/(2(L+lambda))
// with sqrt the lower Cholesky factor (column i). At the paper's alpha = 0.002, beta = 2,
// kappa = 0, L = 3: W0m = -249999, W0c = -249996, Wi = 41666.67 (printed rounded: -2.499e5,
// -2.5e5, 0.416e5).
// Time update (eq. 22-24): chi_i <- f(chi_i, u_{k-1}); x^- = sum W^m chi_i;
//   P^- = sum W^c (chi_i - x^-)(chi_i - x^-)' + Q_k. The propagated points go through h
// without being redrawn (eq. 25-26, the paper's form: Q_k then does not reach P_yy and P_xy);
// redraw_after_prediction: true draws them again around (x^-, P^-), which makes the filter the
// Kalman filter on a linear model. Measurement update (eq. 27-31):
//   P_yy = sum W^c (Y_i - y^)(Y_i - y^)' + R,  P_xy = sum W^c (chi_i - x^-)(Y_i - y^)'
//   K = P_xy P_yy^-1,  x = x^- + K (y - y^),  P = P^- - K P_yy K'.
// Sums about the centre point (not in the paper): with alpha = 0.002 the weights are ~1e5 with
// opposite signs and the points sit 0.35 % of a sigma from the mean, so sum W_i chi_i on raw
// values cancels catastrophically (in float: ~1.5 % of |x|). Every sum here is taken over
// deviations d_i = chi_i - chi_0:  x^- = chi_0 + sum_{i>=1} Wi d_i  (sum W^m = 1 exactly), and
//   P^- = W0c dbar dbar' + sum_{i>=1} Wi (d_i - dbar)(d_i - dbar)' + Q,  dbar = x^- - chi_0,
// which is the same sum with every term O(spread) instead of O(|x|).
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread
// (fixed-capacity Eigen storage: no allocation).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <type_traits>

#include "estimator/model_estimator.hpp"

namespace lode::plugins {

namespace ukf {

inline constexpr int kMaxPoints = 2 * nonlinear::kMaxStates + 1;

/// Eigen storage of R x C (either Eigen::Dynamic) holding at most MaxR x MaxC; a single row is
/// stored row-major, as Eigen requires of a fixed row vector.
template <typename Scalar, int R, int C, int MaxR, int MaxC>
using Storage = Eigen::Matrix<Scalar, R, C, (R == 1 && C != 1) ? Eigen::RowMajor : Eigen::ColMajor, MaxR, MaxC>;

/// The weights of eq. 21 for L states.
struct Weights {
  int states = 0;
  double alpha = 1e-3;
  double beta = 2.0;
  double kappa = 0.0;
  double lambda = 0.0;
  double mean0 = 0.0;  ///< W0m
  double cov0 = 0.0;   ///< W0c
  double other = 0.0;  ///< Wi = W^m_i = W^c_i, i = 1..2L

  static Weights make(int states, double alpha, double beta, double kappa) {
    Weights w;
    w.states = states;
    w.alpha = alpha;
    w.beta = beta;
    w.kappa = kappa;
    const double L = states;
    w.lambda = alpha * alpha * (L + kappa) - L;
    w.mean0 = w.lambda / (L + w.lambda);
    w.cov0 = w.mean0 + (1.0 - alpha * alpha + beta);
    w.other = 1.0 / (2.0 * (L + w.lambda));
    return w;
  }
  /// L + lambda = alpha^2 (L + kappa): the squared spread of the points in sigmas.
  [[nodiscard]] double spread() const { return states + lambda; }
  [[nodiscard]] double mean_sum() const { return mean0 + 2.0 * states * other; }
};

/// How the weighted sums are formed (the block always uses about_centre; raw exists to show
/// in the tests what the paper's literal sums cost in float).
enum class Sums { about_centre, raw };

/// The filter's algebra, templated on the scalar of its storage and arithmetic so that the
/// tests can run it in float (the STM32F4's FPU) as well as in double. The models stay in
/// double (lode's model interfaces are): `f(const double* x, double* x_next)` and
/// `h(const double* x, double* y)`.
///
/// about_centre keeps the points as chi_0 plus deviations d_i = chi_i - chi_0 and never forms
/// chi_0 + d_i in Scalar: at alpha = 0.002 a deviation is ~0.35 % of a sigma, which is a few
/// float ulps of |x|, so even storing chi_i = x + d_i in float would lose it. The model is
/// evaluated at double(chi_0) + double(d_i) and the propagated deviation f(chi_i) - f(chi_0)
/// formed in double before it is stored. raw is the paper's literal form (absolute points,
/// sums of W_i chi_i); with Scalar = double the two agree to rounding.
///
/// States and Channels: the sizes at compile time, or Eigen::Dynamic (any size up to
/// kMaxStates x kMaxChannels, chosen in configure()). Fixed sizes take Eigen's small-matrix
/// code (unrolled products, no size checks, no memmove of capacity-12 storage); both run the
/// same operations in the same order, so a fixed instance gives the dynamic one's results.
template <typename Scalar, int States = Eigen::Dynamic, int Channels = Eigen::Dynamic>
class UnscentedCore {
  static constexpr int kN = States == Eigen::Dynamic ? nonlinear::kMaxStates : States;
  static constexpr int kM = Channels == Eigen::Dynamic ? nonlinear::kMaxChannels : Channels;
  static constexpr int kPoints = States == Eigen::Dynamic ? Eigen::Dynamic : 2 * States + 1;
  static constexpr bool kSized = States != Eigen::Dynamic && Channels != Eigen::Dynamic;

 public:
  using Vector = Storage<Scalar, States, 1, kN, 1>;
  using Matrix = Storage<Scalar, States, States, kN, kN>;
  using Points = Storage<Scalar, States, kPoints, kN, 2 * kN + 1>;
  using MVector = Storage<Scalar, Channels, 1, kM, 1>;
  using MMatrix = Storage<Scalar, Channels, Channels, kM, kM>;
  using MPoints = Storage<Scalar, Channels, kPoints, kM, 2 * kN + 1>;
  using Gain = Storage<Scalar, States, Channels, kN, kM>;

  /// `redraw`: draw the points again around (x^-, P^-) after the prediction, so that the
  /// measurement update sees Q; false is the paper's eq. 25 (the propagated points go through h
  /// as they are), which leaves Q out of P_yy and P_xy.
  void configure(int states, int channels, const Weights& weights, Sums sums = Sums::about_centre,
                 bool redraw = false) {
    redraw_ = redraw;
    n_ = states;
    m_ = channels;
    sums_ = sums;
    points_ = 2 * n_ + 1;
    wm0_ = static_cast<Scalar>(weights.mean0);
    wc0_ = static_cast<Scalar>(weights.cov0);
    wi_ = static_cast<Scalar>(weights.other);
    centre_weight_ = static_cast<Scalar>(weights.beta - weights.alpha * weights.alpha);
    spread_ = static_cast<Scalar>(weights.spread());
    x_.setZero(n_);
    P_.setIdentity(n_, n_);
    centre_.setZero(n_);
    chi_.setZero(n_, points_);
    factor_.setZero(n_, n_);
    y_centre_.setZero(m_);
    upsilon_.setZero(m_, points_);
    innovation_.setZero(m_);
    innovation_variance_.setZero(m_);
    y_hat_.setZero(m_);
    gain_.setZero(n_, m_);
    points_mean_.setZero(n_);
    points_mean_valid_ = false;
  }

  /// x and P: any Eigen storage of the configured sizes (e.g. the block's capacity-12 ones).
  template <class X, class Cov>
  void set(const X& x, const Cov& P) noexcept {
    x_ = x;
    P_ = P;
  }

  /// eq. 20: points around (x, P). False if (L + lambda) P is not positive definite. Forced
  /// inline: as a member of a class template in a position-independent plugin it was called
  /// through the PLT.
  [[gnu::always_inline]] bool draw() noexcept {
    points_mean_valid_ = false;
    if constexpr (States == 3) {
      if (!cholesky_3x3(spread_ * P_, factor_)) return false;
    } else {
      llt_.compute(spread_ * P_);
      if (llt_.info() != Eigen::Success) return false;
      factor_ = llt_.matrixLLT();
    }
    const Matrix& S = factor_;  // L in the lower triangle (its upper part is not read)
    centre_ = x_;
    chi_.col(0).setZero();
    for (int i = 0; i < n(); ++i) {
      for (int j = 0; j < i; ++j) {
        chi_(j, 1 + i) = Scalar(0);
        chi_(j, 1 + n() + i) = -Scalar(0);  // as -S.col(i) of the zero-filled factor
      }
      for (int j = i; j < n(); ++j) {
        chi_(j, 1 + i) = S(j, i);
        chi_(j, 1 + n() + i) = -S(j, i);
      }
    }
    if (sums_ == Sums::raw) {  // absolute points
      for (int i = 0; i < points(); ++i) chi_.col(i) += x_;
      return chi_.allFinite();
    }
    // The deviations are +-L (and zeros): finite exactly when the factor's lower triangle is.
    for (int i = 0; i < n(); ++i) {
      for (int j = i; j < n(); ++j) {
        if (!std::isfinite(S(j, i))) return false;
      }
    }
    return true;
  }

  /// eq. 22-24: push the points through f and form x^-, P^- (+ Q). The state is committed
  /// only if finite; returns false otherwise.
  // predict() and update() are forced inline (into the block's cycle) for the same reason
  // as draw().
  template <class F, class Cov>
  [[gnu::always_inline]] bool predict(F&& f, const Cov& Q) noexcept {
    if (sums_ == Sums::about_centre) return predict_about_centre(f, Q);
    // Raw sums: the points themselves, not deviations from a centre.
    std::array<double, kN> x, next;  // the first n_ of each are written before they are read
    for (int i = 0; i < points(); ++i) {
      for (int j = 0; j < n(); ++j) x[j] = static_cast<double>(chi_(j, i));
      one_point(f, x.data(), next.data());
      for (int j = 0; j < n(); ++j) chi_(j, i) = static_cast<Scalar>(next[j]);
    }
    Vector mean;
    Matrix cov;
    moments(mean, cov);
    cov += Q;
    cov = (Scalar(0.5) * (cov + cov.transpose())).eval();
    if (!mean.allFinite() || !cov.allFinite()) return false;
    x_ = mean;
    P_ = cov;
    return redraw_ ? draw() : true;
  }

  /// eq. 25-31 with the current points (propagated, or drawn when there was no prediction).
  template <class H, class Y, class Noise>
  [[gnu::always_inline]] bool update(H&& h, const Y& y, const Noise& R) noexcept {
    if (sums_ == Sums::about_centre && m() == 1) return update_about_centre(h, y(0), R(0, 0));
    std::array<double, kN> x;  // the first n_ (m_) of each are written before they are read
    std::array<double, kM> base, out;
    MVector y_hat;
    Vector x_dev;  // x^- relative to the centre point (about_centre) or x^- itself (raw)
    MVector y_dev;  // y^ relative to Y_0 (about_centre)
    y_hat.resize(m_);
    x_dev.setZero(n_);
    y_dev.setZero(m_);
    if (sums_ == Sums::about_centre) {
      for (int j = 0; j < n(); ++j) x[j] = static_cast<double>(centre_(j));
      one_point(h, x.data(), base.data());
      upsilon_.col(0).setZero();
      for (int i = 1; i < points(); ++i) {
        for (int j = 0; j < n(); ++j) x[j] = static_cast<double>(centre_(j)) + static_cast<double>(chi_(j, i));
        one_point(h, x.data(), out.data());
        for (int c = 0; c < m(); ++c) upsilon_(c, i) = static_cast<Scalar>(out[c] - base[c]);
      }
      for (int i = 1; i < points(); ++i) {
        x_dev += wi_ * chi_.col(i);
        y_dev += wi_ * upsilon_.col(i);
      }
      for (int c = 0; c < m(); ++c) y_centre_(c) = static_cast<Scalar>(base[c]);
      y_hat = y_centre_ + y_dev;
    } else {
      for (int i = 0; i < points(); ++i) {
        for (int j = 0; j < n(); ++j) x[j] = static_cast<double>(chi_(j, i));
        one_point(h, x.data(), out.data());
        for (int c = 0; c < m(); ++c) upsilon_(c, i) = static_cast<Scalar>(out[c]);
      }
      y_hat = wm0_ * upsilon_.col(0);
      for (int i = 1; i < points(); ++i) y_hat += wi_ * upsilon_.col(i);
    }
    MMatrix Pyy = R;
    Gain Pxy = Gain::Zero(n_, m_);
    for (int i = 0; i < points(); ++i) {
      const Scalar w = i == 0 ? wc0_ : wi_;
      // chi_i - x^- and Y_i - y^, from deviations (about_centre) or absolute values (raw).
      const Vector dx = sums_ == Sums::about_centre ? Vector(chi_.col(i) - x_dev) : Vector(chi_.col(i) - x_);
      const MVector dy =
          sums_ == Sums::about_centre ? MVector(upsilon_.col(i) - y_dev) : MVector(upsilon_.col(i) - y_hat);
      Pyy.noalias() += w * dy * dy.transpose();
      Pxy.noalias() += w * dx * dy.transpose();
    }
    Gain K;  // eq. 29
    if constexpr (Channels == 1) {
      // P_yy is a number (symmetric as it is): its Cholesky factor is sqrt(P_yy) and the two
      // triangular solves scale by its reciprocal, as Eigen's LLT solve does.
      if (!(Pyy(0, 0) > Scalar(0)) && !std::isnan(Pyy(0, 0))) return false;
      const Scalar inverse_root = Scalar(1) / std::sqrt(Pyy(0, 0));
      K = (Pxy * inverse_root) * inverse_root;
    } else {
      Pyy = (Scalar(0.5) * (Pyy + Pyy.transpose())).eval();
      Eigen::LLT<MMatrix> pyy_llt(Pyy);
      if (pyy_llt.info() != Eigen::Success) return false;
      K = pyy_llt.solve(Pxy.transpose()).transpose();
    }
    MVector innovation = y - y_hat;
    if (sums_ == Sums::about_centre) innovation = (y - y_centre_) - y_dev;  // no cancellation of |y|
    Vector x_new = x_ + K * innovation;                                      // eq. 30
    Matrix P = P_;
    P.noalias() -= K * Pyy * K.transpose();                                 // eq. 31
    P = (Scalar(0.5) * (P + P.transpose())).eval();
    if (!x_new.allFinite() || !P.allFinite()) return false;
    x_ = x_new;
    P_ = P;
    innovation_ = innovation;
    innovation_variance_ = Pyy.diagonal();
    y_hat_ = y_hat;
    gain_ = K;
    return true;
  }

  [[nodiscard]] const Vector& x() const noexcept { return x_; }
  [[nodiscard]] const Matrix& P() const noexcept { return P_; }
  [[nodiscard]] const MVector& innovation() const noexcept { return innovation_; }
  /// diag(P_yy) of the last update (P_yy includes R).
  [[nodiscard]] const MVector& innovation_variance() const noexcept { return innovation_variance_; }
  [[nodiscard]] const MVector& predicted_measurement() const noexcept { return y_hat_; }
  [[nodiscard]] const Gain& gain() const noexcept { return gain_; }

 private:
  /// The points chi_0 and chi_0 + d_i (i = 1 ... 2N), N doubles each one after another, each
  /// formed in double as the model takes it.
  [[gnu::always_inline]] void absolute_points(std::array<double, kN*(2 * kN + 1)>& points) const noexcept {
    const int N = n();
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) points[j] = static_cast<double>(centre_(j));
    for (int i = 1; i < 2 * N + 1; ++i) {
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) points[i * N + j] = static_cast<double>(centre_(j)) + static_cast<double>(chi_(j, i));
    }
  }

  /// Whether a model callable takes every point in one call, model(points, count, results),
  /// rather than one, model(point, result).
  template <class Model>
  static constexpr bool kTakesPoints = std::is_invocable_v<Model&, const double*, std::size_t, double*>;

  /// model at one point, whichever form it takes.
  template <class Model>
  static void one_point(Model& model, const double* point, double* result) noexcept {
    if constexpr (kTakesPoints<Model>) {
      model(point, std::size_t{1}, result);
    } else {
      model(point, result);
    }
  }

  /// model at each of the 2N + 1 points (N doubles each), the results `width` apart: in one
  /// call when the model takes them all (model(points, count, results): one virtual call to a
  /// plugin instead of one per point), else point by point (model(point, result)).
  template <class Model>
  [[gnu::always_inline]] void each_point(Model& model, const double* points, double* results, int width) const noexcept {
    const int N = n();
    const int count = 2 * N + 1;
    if constexpr (kTakesPoints<Model>) {
      model(points, static_cast<std::size_t>(count), results);
    } else {
      for (int i = 0; i < count; ++i) model(points + i * N, results + i * width);
    }
  }

  /// out = the symmetric matrix whose upper triangle (row j <= column k) is upper[j + k n]:
  /// formed once and mirrored, so P is exactly symmetric without averaging it with its
  /// transpose. False when a coefficient is not finite (one test from independent per-element
  /// tests: a chain of dependent sums would wait on each add).
  [[gnu::always_inline]] bool mirrored(const std::array<Scalar, kN * kN>& upper, Matrix& out) const noexcept {
    const int N = n();
    out.resize(N, N);  // a no-op for fixed sizes, no allocation for the capacity-sized ones
    bool finite = true;
#pragma GCC unroll 12
    for (int k = 0; k < N; ++k) {
#pragma GCC unroll 12
      for (int j = 0; j <= k; ++j) {
        const Scalar v = upper[j + k * N];
        out(j, k) = v;
        out(k, j) = v;
        finite &= std::isfinite(v);
      }
    }
    return finite;
  }

  /// sum_{i>=1} d_i d_i' (upper triangle, column-major) and sum_{i>=1} d_i of the deviations
  /// in chi_, the points i and N + i (mirror images when drawn) added first: shorter chains
  /// of dependent adds than one sum over the 2N points, and the pair's +-L cancel early.
  [[gnu::always_inline]] void deviation_sums(std::array<Scalar, kN>& sum,
                                             std::array<Scalar, kN * kN>& outer) const noexcept {
    const int N = n();
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) sum[j] = Scalar(0);
#pragma GCC unroll 12
    for (int k = 0; k < N; ++k) {
#pragma GCC unroll 12
      for (int j = 0; j <= k; ++j) outer[j + k * N] = Scalar(0);
    }
#pragma GCC unroll 12
    for (int i = 1; i <= N; ++i) {
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) sum[j] += chi_(j, i) + chi_(j, N + i);
#pragma GCC unroll 12
      for (int k = 0; k < N; ++k) {
#pragma GCC unroll 12
        for (int j = 0; j <= k; ++j) {
          outer[j + k * N] += chi_(j, i) * chi_(k, i) + chi_(j, N + i) * chi_(k, N + i);
        }
      }
    }
  }

  /// predict() for sizes known at compile time, sums about the centre point, in one pass:
  /// with dbar = sum_{i>=1} Wi d_i and d_0 = 0, the moment about the mean expands to
  ///   sum_i W^c_i (d_i - dbar)(d_i - dbar)' = Wi sum_{i>=1} d_i d_i' + (beta - alpha^2) dbar dbar'
  /// (sum W^m = 1 and W0c - W0m = 1 - alpha^2 + beta), so the points are read once and the
  /// +-1e5 weights never multiply dbar dbar' (the generic code's W0c term cancels against its
  /// other terms; here the coefficient is ~2). Equal to the generic code's result to rounding
  /// (~1e-15 relative), not bit for bit.
  template <class F, class Cov>
  [[gnu::always_inline]] bool predict_about_centre(F& f, const Cov& Q) noexcept {
    const int N = n();
    std::array<double, kN*(2 * kN + 1)> points, propagated;  // the first N (2N + 1) written first
    absolute_points(points);
    each_point(f, points.data(), propagated.data(), N);
    const double* base = propagated.data();
    for (int i = 1; i < 2 * N + 1; ++i) {
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) chi_(j, i) = static_cast<Scalar>(propagated[i * N + j] - base[j]);
    }
    std::array<Scalar, kN> sum{};
    std::array<Scalar, kN * kN> cov{};  // upper triangle, column-major as Matrix
    deviation_sums(sum, cov);
    std::array<Scalar, kN> dbar{};  // x^- - chi_0
    bool finite = true;
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) {
      dbar[j] = wi_ * sum[j];
      centre_(j) = static_cast<Scalar>(base[j]);
      x_(j) = centre_(j) + dbar[j];
      points_mean_(j) = dbar[j];
      finite &= std::isfinite(x_(j));
    }
    points_mean_valid_ = true;  // until the points are drawn again
#pragma GCC unroll 12
    for (int k = 0; k < N; ++k) {
#pragma GCC unroll 12
      for (int j = 0; j <= k; ++j) {
        cov[j + k * N] = (wi_ * cov[j + k * N] + (centre_weight_ * dbar[j]) * dbar[k]) + Q(j, k);
      }
    }
    // A non-finite x_ is kept only until the caller restores the last estimate on the fault.
    finite &= mirrored(cov, P_);
    if (!finite) return false;
    return redraw_ ? draw() : true;
  }

  /// update() for sizes known at compile time and one channel, sums about the centre point,
  /// in one pass as predict_sized() (P_yy = Wi sum Y_i^2 + (beta - alpha^2) ybar^2 + R, P_xy
  /// alike, deviations from Y_0); P_yy is a number, so K = P_xy / P_yy and
  /// P = P^- - K P_yy K' = P^- - K P_xy', its upper triangle mirrored.
  template <class H>
  [[gnu::always_inline]] bool update_about_centre(H& h, Scalar y, Scalar r) noexcept {
    const int N = n();
    std::array<double, kN*(2 * kN + 1)> points;  // the first N (2N + 1) written first
    std::array<double, 2 * kN + 1> measured;
    absolute_points(points);
    each_point(h, points.data(), measured.data(), 1);
    const double base = measured[0];
    upsilon_(0, 0) = Scalar(0);
    for (int i = 1; i < 2 * N + 1; ++i) upsilon_(0, i) = static_cast<Scalar>(measured[i] - base);
    // x^- relative to the centre point: the prediction left it in points_mean_ when these
    // are its points.
    std::array<Scalar, kN> x_dev{};
    if (points_mean_valid_) {
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) x_dev[j] = points_mean_(j);
    } else {
      std::array<Scalar, kN> sum{};
#pragma GCC unroll 12
      for (int i = 1; i <= N; ++i) {
#pragma GCC unroll 12
        for (int j = 0; j < N; ++j) sum[j] += chi_(j, i) + chi_(j, N + i);
      }
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) x_dev[j] = wi_ * sum[j];
    }
    Scalar y_sum = Scalar(0), yy = Scalar(0);
    std::array<Scalar, kN> xy{};
#pragma GCC unroll 12
    for (int i = 1; i <= N; ++i) {
      const Scalar a = upsilon_(0, i), b = upsilon_(0, N + i);
      y_sum += a + b;
      yy += a * a + b * b;
#pragma GCC unroll 12
      for (int j = 0; j < N; ++j) xy[j] += chi_(j, i) * a + chi_(j, N + i) * b;
    }
    const Scalar y_dev = wi_ * y_sum;  // y^ relative to Y_0
    const Scalar y_centre = static_cast<Scalar>(base);
    const Scalar y_hat = y_centre + y_dev;
    const Scalar weighted_y_dev = centre_weight_ * y_dev;
    const Scalar Pyy = (wi_ * yy + weighted_y_dev * y_dev) + r;
    // eq. 29. Not > 0 covers NaN: a non-finite P_yy faults here.
    if (!(Pyy > Scalar(0))) return false;
    std::array<Scalar, kN> Pxy{}, K{};
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) {
      Pxy[j] = wi_ * xy[j] + x_dev[j] * weighted_y_dev;
      K[j] = Pxy[j] / Pyy;
    }
    const Scalar innovation = (y - y_centre) - y_dev;  // no cancellation of |y|
    std::array<Scalar, kN> x_new{};
    bool finite = true;
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) {
      x_new[j] = x_(j) + K[j] * innovation;  // eq. 30
      finite &= std::isfinite(x_new[j]);
    }
    std::array<Scalar, kN * kN> P{};  // eq. 31, the upper triangle
#pragma GCC unroll 12
    for (int k = 0; k < N; ++k) {
#pragma GCC unroll 12
      for (int j = 0; j <= k; ++j) P[j + k * N] = P_(j, k) - K[j] * Pxy[k];
    }
    Matrix P_sym;
    finite &= mirrored(P, P_sym);
    if (!finite) return false;
#pragma GCC unroll 12
    for (int j = 0; j < N; ++j) {
      x_(j) = x_new[j];
      gain_(j, 0) = K[j];
    }
    P_ = P_sym;
    y_centre_(0) = y_centre;
    innovation_(0) = innovation;
    innovation_variance_(0) = Pyy;
    y_hat_(0) = y_hat;
    return true;
  }

  /// The lower Cholesky factor of a 3 x 3 A into L's lower triangle, with the operations of
  /// Eigen's LLT in its order (so the same bits) without its run-time-sized blocks. False
  /// where Eigen's fails: a pivot <= 0 (a NaN pivot goes on, as there, and shows as NaN in L).
  template <class A>
  static bool cholesky_3x3(const A& a, Matrix& L) noexcept {
    Scalar x = a(0, 0);
    if (x <= Scalar(0)) return false;
    const Scalar l00 = std::sqrt(x);
    const Scalar l10 = a(1, 0) / l00;
    const Scalar l20 = a(2, 0) / l00;
    x = a(1, 1) - l10 * l10;
    if (x <= Scalar(0)) return false;
    const Scalar l11 = std::sqrt(x);
    const Scalar l21 = (a(2, 1) - l20 * l10) / l11;
    x = a(2, 2) - (l20 * l20 + l21 * l21);
    if (x <= Scalar(0)) return false;
    L(0, 0) = l00;
    L(1, 0) = l10;
    L(2, 0) = l20;
    L(1, 1) = l11;
    L(2, 1) = l21;
    L(2, 2) = std::sqrt(x);
    return true;
  }

  /// cov += w d d' (d: States numbers), element by element as Eigen forms it: (w d_j) d_k.
  static void rank_one_update(Matrix& cov, Scalar w, const Scalar* d) noexcept {
#pragma GCC unroll 12
    for (int k = 0; k < States; ++k) {
#pragma GCC unroll 12
      for (int j = 0; j < States; ++j) cov(j, k) += (w * d[j]) * d[k];
    }
  }

  /// Weighted mean and covariance of the points (without Q).
  void moments(Vector& mean, Matrix& cov) const noexcept {
    cov.setZero(n_, n_);
    if constexpr (States != Eigen::Dynamic) {
      if (sums_ == Sums::about_centre) {
        // The generic branch below written out for a size known at compile time, the same
        // operations element by element: dbar_j += Wi d_ij, then cov += (w d_j) d_k.
        std::array<Scalar, States> dbar{};
        for (int i = 1; i < points(); ++i) {
#pragma GCC unroll 12
          for (int j = 0; j < States; ++j) dbar[j] += wi_ * chi_(j, i);
        }
#pragma GCC unroll 12
        for (int j = 0; j < States; ++j) mean(j) = centre_(j) + dbar[j];
        rank_one_update(cov, wc0_, dbar.data());
        for (int i = 1; i < points(); ++i) {
          std::array<Scalar, States> d;
#pragma GCC unroll 12
          for (int j = 0; j < States; ++j) d[j] = chi_(j, i) - dbar[j];
          rank_one_update(cov, wi_, d.data());
        }
        return;
      }
    }
    if (sums_ == Sums::about_centre) {
      Vector dbar = Vector::Zero(n_);  // x^- - chi_0 = sum_{i>=1} Wi d_i (sum of W^m = 1)
      for (int i = 1; i < points(); ++i) dbar += wi_ * chi_.col(i);
      mean = centre_ + dbar;
      cov.noalias() += wc0_ * dbar * dbar.transpose();
      for (int i = 1; i < points(); ++i) {
        const Vector d = chi_.col(i) - dbar;
        cov.noalias() += wi_ * d * d.transpose();
      }
      return;
    }
    mean = wm0_ * chi_.col(0);
    for (int i = 1; i < points(); ++i) mean += wi_ * chi_.col(i);
    for (int i = 0; i < points(); ++i) {
      const Vector d = chi_.col(i) - mean;
      cov.noalias() += (i == 0 ? wc0_ : wi_) * d * d.transpose();
    }
  }

  // The sizes, as constants when they are known at compile time (the loops then unroll).
  [[nodiscard]] int n() const noexcept { return States == Eigen::Dynamic ? n_ : States; }
  [[nodiscard]] int m() const noexcept { return Channels == Eigen::Dynamic ? m_ : Channels; }
  [[nodiscard]] int points() const noexcept { return States == Eigen::Dynamic ? points_ : 2 * States + 1; }

  int n_ = 0;
  int m_ = 0;
  int points_ = 1;
  Sums sums_ = Sums::about_centre;
  bool redraw_ = false;
  Scalar wm0_{}, wc0_{}, wi_{}, spread_{};
  Scalar centre_weight_{};  ///< beta - alpha^2 = W0c - W0m: the weight of dbar dbar' in the one-pass sums
  Vector x_;
  Matrix P_;
  Vector centre_;     ///< chi_0 (about_centre)
  Points chi_;        ///< deviations d_i (about_centre, d_0 = 0) or absolute points (raw)
  MVector y_centre_;  ///< h(chi_0) (about_centre)
  MPoints upsilon_;   ///< deviations h(chi_i) - h(chi_0), or absolute (raw)
  MVector innovation_;
  MVector innovation_variance_;
  MVector y_hat_;
  Gain gain_;
  Eigen::LLT<Matrix> llt_;
  Matrix factor_;  ///< the lower Cholesky factor of (L + lambda) P
  Vector points_mean_;              ///< sum_{i>=1} Wi d_i of the current points (sized prediction)
  bool points_mean_valid_ = false;  ///< the prediction has formed points_mean_ from chi_ as it is
};

}  // namespace ukf

class UnscentedEstimator final : public nonlinear::ModelEstimator {
 public:
  [[nodiscard]] const ukf::Weights& weights() const { return weights_; }
  /// K of the last update (a copy off the RT thread).
  [[nodiscard]] const nonlinear::GainMatrix& gain() const;
  /// Whether configure() chose a core sized at compile time for the model's (n, m).
  [[nodiscard]] bool fixed_size() const { return fixed_; }

 protected:
  void read_filter_params(Params& params) override;
  Status prepare_filter(Params& params) override;
  void reset_filter() noexcept override;
  StepStatus filter_cycle(bool first) noexcept override;
  void describe_filter(Json& out) const override;

 private:
  double alpha_ = 0.002;
  double beta_ = 2.0;
  double kappa_ = 0.0;
  bool redraw_ = false;
  bool compile_time_sizes_ = true;
  ukf::Weights weights_;

  /// A core with its constant operands (Q_k, R) stored in its own sizes, so that step()
  /// mixes no capacity-12 storage into the small products.
  template <int States, int Channels>
  struct Sized {
    using Core = ukf::UnscentedCore<double, States, Channels>;
    Core core;
    typename Core::Matrix Q;
    typename Core::MMatrix R;
    typename Core::MVector y;
  };
  template <class S>
  void prepare(S& sized);
  template <class S>
  StepStatus cycle(S& sized, bool first) noexcept;

  // The sizes of the shipped models (plant.suspension with one gap channel) have their own
  // core; any other (n, m) runs the dynamic one.
  bool fixed_ = false;
  Sized<3, 1> suspension_;
  Sized<Eigen::Dynamic, Eigen::Dynamic> any_;
  mutable nonlinear::GainMatrix gain_copy_;
};

}  // namespace lode::plugins
