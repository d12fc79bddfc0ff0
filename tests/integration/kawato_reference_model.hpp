// Linear closed-loop reference model of one axis of the kawato_planar demo, written from
// Kawato (2005) alone (no plugin code), so that the demo can be checked against its design:
//
//   plant       ZOH double integrator 1/(m s^2) (eq. 4.44-4.47). The board applies the force
//               computed in cycle k over [t_k, t_k+1) (read, blocks, write in one cycle), so
//               p_k+1 = p_k + T v_k + T^2/(2m) u_k, v_k+1 = v_k + T/m u_k: no extra delay.
//   GLSDC       truth + white noise n_k of the variance it reports (R_k, eq. 4.28): one
//               Gauss-Newton step reaches the least-squares pose when the platen moved little.
//   Kalman      constant-acceleration model, Phi and Upsilon of eq. 4.39 at T = 1.25 ms, Q = q
//               (eq. 4.41), steady-state gain from the Riccati recursion of Table III; the output
//               is the propagated state H x^-_k+1 (as the thesis's listing), or H x^+_k.
//   controller  D(s) = K (s + 8.31)(s + 10) / (s (s + 1134)) (eq. 4.48, 4.50) by matched
//               pole-zero: u_k = -a1 u_k-1 - a2 u_k-2 + Kd (e_k + b1 e_k-1 + b2 e_k-2), e = r - y.
//
// Closed-loop state s = [p, v, x^-_k (3 Kalman states), two controller states], inputs n_k
// (measurement noise) and r_k (reference): s_k+1 = F s_k + g_n n_k + g_r r_k.
#pragma once

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace kawato_model {

/// One axis of the design: Kawato (2005) eq. 4.44-4.51 and the Kalman q of eq. 4.41.
struct AxisDesign {
  const char* name;
  double inertia;          ///< 6.20 kg (X, Y) or 0.054 kg m^2 (theta_z)
  double controller_gain;  ///< K of D(s): 4.09e5 N/m (X, Y), 7.6e3 N m/rad (theta_z)
  double kalman_q;         ///< jerk variance: 1e2 m^2/s^6 (X, Y), 1e5 rad^2/s^6 (theta_z)
};

constexpr double kZero1 = -8.31, kZero2 = -10.0, kLagPole = -1134.0;  // D(s), eq. 4.48

/// D(z) = gain (z^2 + num[1] z + num[2]) / (z^2 + den[1] z + den[2]).
struct DiscreteController {
  double gain = 0.0;
  double num[3] = {1.0, 0.0, 0.0};
  double den[3] = {1.0, 0.0, 0.0};
};

/// Matched pole-zero: z = e^{sT} for every root; both D have one integrator, so the gain is
/// matched on the velocity constant lim s D(s) = lim (z - 1)/T D(z).
inline DiscreteController matched_pole_zero(double gain_s, double period) {
  const double z1 = std::exp(kZero1 * period), z2 = std::exp(kZero2 * period);
  const double p2 = std::exp(kLagPole * period);
  DiscreteController d;
  d.num[1] = -(z1 + z2);
  d.num[2] = z1 * z2;
  d.den[1] = -(1.0 + p2);
  d.den[2] = p2;
  const double velocity_constant = gain_s * kZero1 * kZero2 / -kLagPole;
  d.gain = velocity_constant * period * (1.0 - p2) / ((1.0 - z1) * (1.0 - z2));
  return d;
}

struct KalmanSteadyState {
  Eigen::Matrix3d phi;
  Eigen::Vector3d gain;  ///< K = P^- H' (H P^- H' + r)^-1 at convergence
  int iterations = 0;
  bool converged = false;
};

/// Riccati recursion of Table III from P0 = p0 I until no gain element moves by 1e-13 of itself.
inline KalmanSteadyState kalman_steady_state(double q, double r, double period, double p0 = 1e-8) {
  const double t = period;
  KalmanSteadyState ss;
  ss.phi << 1, t, t * t / 2, 0, 1, t, 0, 0, 1;
  const Eigen::Vector3d upsilon(t * t * t / 6, t * t / 2, t);
  Eigen::Matrix3d prior = p0 * Eigen::Matrix3d::Identity();
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (ss.iterations = 1; ss.iterations <= 1000000; ++ss.iterations) {
    ss.gain = prior.col(0) / (prior(0, 0) + r);
    const Eigen::Matrix3d posterior = prior - ss.gain * prior.row(0);
    prior = ss.phi * posterior * ss.phi.transpose() + q * upsilon * upsilon.transpose();
    if (((ss.gain - previous).array().abs() <= 1e-13 * ss.gain.array().abs()).all()) {
      ss.converged = true;
      break;
    }
    previous = ss.gain;
  }
  return ss;
}

constexpr int kStates = 7;
using Matrix = Eigen::Matrix<double, kStates, kStates>;
using Vector = Eigen::Matrix<double, kStates, 1>;
using Row = Eigen::Matrix<double, 1, kStates>;

/// y_k = c s_k + d n_k
struct Output {
  Row c = Row::Zero();
  double d = 0.0;
};

struct ClosedLoop {
  Matrix f = Matrix::Zero();
  Vector g_noise = Vector::Zero();
  Vector g_reference = Vector::Zero();
  Output position;     ///< true platen position p_k
  Output force;        ///< controller output u_k (its reference term is left out: noise only)
  Output measurement;  ///< GLSDC output p_k + n_k
  KalmanSteadyState kalman;
  DiscreteController controller;
};

inline ClosedLoop closed_loop(const AxisDesign& axis, double kalman_r, double period, bool output_predicted = true) {
  ClosedLoop cl;
  const double t = period, m = axis.inertia;
  cl.kalman = kalman_steady_state(axis.kalman_q, kalman_r, period);
  cl.controller = matched_pole_zero(axis.controller_gain, period);
  const Eigen::Matrix3d& phi = cl.kalman.phi;
  const Eigen::Vector3d& k = cl.kalman.gain;
  enum { P = 0, V = 1, X = 2, C0 = 5, C1 = 6 };

  // Kalman: x+ = (I - K H) x- + K (p + n); x-_k+1 = Phi x+; the controller sees H Phi x+ or H x+.
  Eigen::Matrix3d i_minus_kh = Eigen::Matrix3d::Identity();
  i_minus_kh.col(0) -= k;
  const Eigen::RowVector3d h_out = output_predicted ? Eigen::RowVector3d(phi.row(0)) : Eigen::RowVector3d(1, 0, 0);
  Output seen;  // the controller's measurement
  seen.c(P) = h_out.dot(k);
  seen.c.segment<3>(X) = h_out * i_minus_kh;
  seen.d = h_out.dot(k);

  // Controller, transposed direct form II of D(z): u = b0 e + c0, c0' = b1 e - a1 u + c1,
  // c1' = b2 e - a2 u, with e = r - seen.
  const DiscreteController& d = cl.controller;
  const double b[3] = {d.gain * d.num[0], d.gain * d.num[1], d.gain * d.num[2]};
  Output error;  // e without r
  error.c = -seen.c;
  error.d = -seen.d;
  cl.force.c = b[0] * error.c;
  cl.force.c(C0) += 1.0;
  cl.force.d = b[0] * error.d;
  const double force_r = b[0];

  Matrix& f = cl.f;
  f(P, P) = 1.0;
  f(P, V) = t;
  f(V, V) = 1.0;
  const Eigen::Vector2d plant_input(t * t / (2 * m), t / m);
  f.block<2, kStates>(P, 0) += plant_input * cl.force.c;
  cl.g_noise.segment<2>(P) += plant_input * cl.force.d;
  cl.g_reference.segment<2>(P) += plant_input * force_r;

  f.block<3, 3>(X, X) += phi * i_minus_kh;
  f.block<3, 1>(X, P) += phi * k;
  cl.g_noise.segment<3>(X) += phi * k;

  f.row(C0) += b[1] * error.c - d.den[1] * cl.force.c;
  f(C0, C1) += 1.0;
  cl.g_noise(C0) += b[1] * error.d - d.den[1] * cl.force.d;
  cl.g_reference(C0) += b[1] - d.den[1] * force_r;
  f.row(C1) += b[2] * error.c - d.den[2] * cl.force.c;
  cl.g_noise(C1) += b[2] * error.d - d.den[2] * cl.force.d;
  cl.g_reference(C1) += b[2] - d.den[2] * force_r;

  cl.position.c(P) = 1.0;
  cl.measurement.c(P) = 1.0;
  cl.measurement.d = 1.0;
  return cl;
}

/// Stationary state covariance: X = F X F' + q g g', by doubling (Smith's method).
inline Matrix state_covariance(const ClosedLoop& cl, double noise_variance) {
  Matrix x = noise_variance * cl.g_noise * cl.g_noise.transpose();
  Matrix a = cl.f;
  for (int i = 0; i < 40; ++i) {
    x += a * x * a.transpose();
    a = a * a;
  }
  return x;
}

/// Autocovariance gamma(tau), tau = 0 .. lags-1, of y = c s + d n in the stationary loop:
/// gamma(0) = c X c' + d^2 q, gamma(tau >= 1) = c F^tau X c' + c F^(tau-1) g_n d q.
inline std::vector<double> autocovariance(const ClosedLoop& cl, const Output& y, const Matrix& x,
                                          double noise_variance, int lags) {
  std::vector<double> gamma(static_cast<std::size_t>(lags));
  Vector state_term = x * y.c.transpose();
  Vector noise_term = cl.g_noise * y.d * noise_variance;
  gamma[0] = y.c.dot(state_term) + y.d * y.d * noise_variance;
  for (int tau = 1; tau < lags; ++tau) {
    state_term = cl.f * state_term;
    gamma[static_cast<std::size_t>(tau)] = y.c.dot(state_term + noise_term);
    noise_term = cl.f * noise_term;
  }
  return gamma;
}

/// Relative standard error of a sample standard deviation over n samples of a stationary
/// Gaussian sequence: var(s^2) = (2 / n) sum_tau gamma(tau)^2 (Bartlett), so
/// sd(s) / sigma = sqrt(sum_tau rho(tau)^2 / (2 n)); n / sum rho^2 is the effective sample size.
inline double std_relative_error(const std::vector<double>& gamma, std::size_t n) {
  double sum_rho2 = 1.0;
  for (std::size_t tau = 1; tau < gamma.size() && tau < n; ++tau) {
    const double rho = gamma[tau] / gamma[0];
    sum_rho2 += 2.0 * rho * rho * (1.0 - static_cast<double>(tau) / static_cast<double>(n));
  }
  return std::sqrt(sum_rho2 / (2.0 * static_cast<double>(n)));
}

/// Noise-free position response to a reference step of `amplitude` at sample 0.
inline std::vector<double> step_response(const ClosedLoop& cl, double amplitude, std::size_t samples) {
  std::vector<double> y(samples);
  Vector s = Vector::Zero();
  for (std::size_t k = 0; k < samples; ++k) {
    y[k] = cl.position.c.dot(s);
    s = cl.f * s + cl.g_reference * amplitude;
  }
  return y;
}

/// A noise-free run replayed through the design: the Kalman gain follows the recursion of
/// Table III with the R_k the GLSDC reported on each cycle (from P0 = p0 I, the position starting
/// at the first measurement, as the block does) instead of its steady state, and the measurement
/// is p_k + e_k with e_k the GLSDC's own error in that run. Fed those two sequences, the model
/// has the run's dynamics exactly: what remains is floating-point rounding. Returns p_k.
inline std::vector<double> replay(const AxisDesign& axis, double period, const std::vector<double>& reference,
                                  const std::vector<double>& r, const std::vector<double>& glsdc_error,
                                  double p0 = 1e-8) {
  const double t = period, m = axis.inertia;
  const DiscreteController d = matched_pole_zero(axis.controller_gain, period);
  Eigen::Matrix3d phi;
  phi << 1, t, t * t / 2, 0, 1, t, 0, 0, 1;
  const Eigen::Vector3d upsilon(t * t * t / 6, t * t / 2, t);
  Eigen::Matrix3d prior = p0 * Eigen::Matrix3d::Identity();
  Eigen::Vector3d estimate = Eigen::Vector3d::Zero();
  double p = 0, v = 0, c0 = 0, c1 = 0;
  std::vector<double> out(reference.size());
  for (std::size_t k = 0; k < reference.size(); ++k) {
    out[k] = p;
    const double y = p + glsdc_error[k];
    if (k == 0) estimate(0) = y;
    const Eigen::Vector3d gain = prior.col(0) / (prior(0, 0) + r[k]);
    estimate = phi * (estimate + gain * (y - estimate(0)));
    prior = phi * (prior - gain * prior.row(0)) * phi.transpose() + axis.kalman_q * upsilon * upsilon.transpose();
    const double e = reference[k] - estimate(0);
    const double u = d.gain * d.num[0] * e + c0;
    c0 = d.gain * d.num[1] * e - d.den[1] * u + c1;
    c1 = d.gain * d.num[2] * e - d.den[2] * u;
    p += t * v + t * t / (2 * m) * u;
    v += t / m * u;
  }
  return out;
}

/// Rise (10 -> 90 %, linearly interpolated first up-crossings), overshoot and settling (last
/// sample outside +-band around the final reference, plus one) of a step response y[0 ..],
/// y[0] being the sample of the step. Same definitions as `lode run`'s summary.
struct StepFigures {
  double rise_s = std::numeric_limits<double>::quiet_NaN();
  double overshoot_pct = 0.0;
  double settling_s = std::numeric_limits<double>::quiet_NaN();
  std::size_t after_10 = 0, after_90 = 0;  ///< first sample at or past the 10 % / 90 % level
  std::size_t peak = 0;
  std::size_t last_outside = 0;
};

inline StepFigures step_figures(const std::vector<double>& y, double reference_before, double final_value,
                                double band, double period) {
  StepFigures f;
  const double sign = final_value > reference_before ? 1.0 : -1.0;  // the reference's direction
  const double span = final_value - y[0];
  auto first_crossing = [&](double level, std::size_t& after) {
    for (std::size_t k = 1; k < y.size(); ++k) {
      const double below = sign * (y[k - 1] - level), above = sign * (y[k] - level);
      if (k == 1 && below >= 0) {
        after = 0;
        return 0.0;
      }
      if (below < 0 && above >= 0) {
        after = k;
        return (static_cast<double>(k - 1) + below / (below - above)) * period;
      }
    }
    return std::numeric_limits<double>::quiet_NaN();
  };
  const double t10 = first_crossing(y[0] + 0.1 * span, f.after_10);
  const double t90 = first_crossing(y[0] + 0.9 * span, f.after_90);
  f.rise_s = t90 - t10;
  double peak = 0.0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    if (sign * (y[k] - final_value) > peak) {
      peak = sign * (y[k] - final_value);
      f.peak = k;
    }
    if (std::abs(y[k] - final_value) > band) f.last_outside = k;
  }
  f.overshoot_pct = 100.0 * peak / std::abs(span);
  if (f.last_outside + 1 < y.size()) f.settling_s = static_cast<double>(f.last_outside + 1) * period;
  return f;
}

}  // namespace kawato_model
