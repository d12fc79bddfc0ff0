#include "lq_integral.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <set>
#include <string>

#include "lode/sdk/json_eigen.hpp"
#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins {

namespace lq_integral {

namespace {

using lode::math::Matrix;
using Complex = std::complex<double>;

/// Closed-loop pos_i / pos*_i at w [rad/s]: the state s = [pos; z; vel] with u = u* - K xi,
/// xi = s - [pos*; 0; 0], so s_{k+1} = (Phi - Gamma K) s_k + (Gamma K_pos - [0; T I; 0]) pos*_k.
Complex reference_response(const Matrix& closed_loop, const Matrix& reference_input, Eigen::Index position,
                           double w_rad_s, double period_s) {
  const Eigen::Index n = closed_loop.rows();
  const Complex z = std::exp(Complex(0.0, w_rad_s * period_s));
  const Eigen::MatrixXcd pencil = z * Eigen::MatrixXcd::Identity(n, n) - closed_loop.cast<Complex>();
  const Eigen::VectorXcd x = pencil.partialPivLu().solve(reference_input.col(position).cast<Complex>());
  return x(position);
}

/// Lowest frequency [Hz] where |pos_i / pos*_i| falls below 1/sqrt(2), or 0 if it does not
/// before Nyquist: a log-spaced scan from 0.01 Hz, then bisection on the bracketing interval.
double bandwidth_hz(const Matrix& closed_loop, const Matrix& reference_input, Eigen::Index position,
                    double period_s) {
  const double nyquist_hz = 0.5 / period_s;
  const double threshold = 1.0 / std::numbers::sqrt2;
  auto magnitude = [&](double f_hz) {
    return std::abs(reference_response(closed_loop, reference_input, position, 2.0 * std::numbers::pi * f_hz, period_s));
  };
  constexpr int kScan = 2000;
  double previous = 0.01;
  for (int i = 1; i <= kScan; ++i) {
    const double f = 0.01 * std::pow(nyquist_hz / 0.01, static_cast<double>(i) / kScan);
    if (magnitude(f) < threshold) {
      double low = previous;
      double high = f;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (low + high);
        (magnitude(mid) < threshold ? high : low) = mid;
      }
      return 0.5 * (low + high);
    }
    previous = f;
  }
  return 0.0;
}

}  // namespace

Expected<Design> design(const Matrix& A, const Matrix& B, bool continuous, double period_s, const Matrix& Q,
                        const Matrix& R) {
  const Eigen::Index p = A.rows() / 2;
  const Eigen::Index m = B.cols();
  Design d;
  d.period_s = period_s;
  if (continuous) {
    const lode::math::DiscreteSystem zoh = lode::math::zoh(A, B, period_s);
    d.plant_A = zoh.Ad;
    d.plant_B = zoh.Bd;
  } else {
    d.plant_A = A;
    d.plant_B = B;
  }
  // [pos; vel] -> [pos; int; vel] with z_{k+1} = z_k + T pos_k, in the order of the printed Q and K.
  const Matrix& Ap = d.plant_A;
  const Matrix identity = Matrix::Identity(p, p);
  d.Phi = Matrix::Zero(3 * p, 3 * p);
  d.Phi.block(0, 0, p, p) = Ap.block(0, 0, p, p);
  d.Phi.block(0, 2 * p, p, p) = Ap.block(0, p, p, p);
  d.Phi.block(p, 0, p, p) = period_s * identity;
  d.Phi.block(p, p, p, p) = identity;
  d.Phi.block(2 * p, 0, p, p) = Ap.block(p, 0, p, p);
  d.Phi.block(2 * p, 2 * p, p, p) = Ap.block(p, p, p, p);
  d.Gamma = Matrix::Zero(3 * p, m);
  d.Gamma.topRows(p) = d.plant_B.topRows(p);
  d.Gamma.bottomRows(p) = d.plant_B.bottomRows(p);
  d.Q = Q;
  d.R = R;

  Expected<lode::math::DareSolution> dare = lode::math::solve_dare_detailed(d.Phi, d.Gamma, Q, R);
  if (!dare) return Status::error("no LQ gain: " + dare.error());
  const Matrix& P = dare->P;
  d.riccati_residual = dare->relative_residual;
  d.K = (R + d.Gamma.transpose() * P * d.Gamma).llt().solve(d.Gamma.transpose() * P * d.Phi);
  const Matrix closed_loop = d.Phi - d.Gamma * d.K;
  d.closed_loop_poles = Eigen::EigenSolver<Matrix>(closed_loop, false).eigenvalues();

  Matrix reference_input = d.Gamma * d.K.leftCols(p);
  reference_input.block(p, 0, p, p) -= period_s * identity;
  for (Eigen::Index i = 0; i < p; ++i) d.bandwidth_hz.push_back(bandwidth_hz(closed_loop, reference_input, i, period_s));
  return d;
}

}  // namespace lq_integral

namespace {

using lode::math::Matrix;
using lq_integral::kMaxInputs;
using lq_integral::kMaxModes;
using lq_integral::kMaxPositions;
using lq_integral::Mode;
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

std::string count_text(std::size_t value) { return std::to_string(value); }

Matrix row_major(const std::vector<double>& values, Eigen::Index rows, Eigen::Index cols) {
  return Eigen::Map<const RowMajor>(values.data(), rows, cols);
}

/// A diagonal (k entries) or full (k*k entries, row-major) weight.
Matrix weight(Params& p, std::string_view key, const std::vector<double>& values, Eigen::Index k,
              const char* what) {
  const auto n = static_cast<std::size_t>(k);
  if (values.size() == n) {
    for (double v : values) {
      if (!(v >= 0.0) || !std::isfinite(v)) {
        p.fail(key, std::string(what) + " diagonal entries must be finite and >= 0, got " + number_text(v));
      }
    }
    return Eigen::Map<const Eigen::VectorXd>(values.data(), k).asDiagonal();
  }
  if (values.size() == n * n) {
    Matrix M = row_major(values, k, k);
    double asymmetry = 0.0;
    double largest = 0.0;
    for (Eigen::Index i = 0; i < k; ++i) {
      for (Eigen::Index j = 0; j < k; ++j) {
        asymmetry = std::max(asymmetry, std::abs(M(i, j) - M(j, i)));
        largest = std::max(largest, std::abs(M(i, j)));
      }
    }
    if (!M.allFinite() || asymmetry > 1e-12 * largest) {
      p.fail(key, std::string(what) + " given in full must be finite and symmetric");
    }
    return M;
  }
  p.fail(key, std::string(what) + ": expected " + count_text(n) + " numbers (the diagonal) or " + count_text(n * n) +
                  " (row-major), got " + count_text(values.size()));
  return Matrix::Identity(k, k);
}

/// One number for every output, or one per output.
std::vector<double> per_output(Params& p, std::string_view key, std::vector<double> values, std::size_t m) {
  if (values.size() == 1 && m > 1) values.assign(m, values.front());
  if (values.size() != m) {
    p.fail(key, "expected one number or " + count_text(m) + " (one per output), got " + count_text(values.size()));
    values.assign(m, 0.0);
  }
  return values;
}

Json text_list(const std::vector<std::string>& values) {
  Json out = Json::array();
  for (const std::string& v : values) out.push(Json(v));
  return out;
}

/// Reads and designs one mode; every problem is reported on `p`.
void read_mode(Params& p, std::size_t index, std::size_t mode_count, const Elements& measurement,
               std::set<std::string>& used_positions, double period_s, Mode& mode) {
  mode.name = p.text("name", "mode" + std::to_string(index));
  std::vector<std::string> positions = p.texts("positions", {});
  if (!p.has("positions")) {
    if (mode_count > 1) {
      p.fail("positions", "with several modes each must list its positions (measurement element names)");
    }
    for (const Element& e : measurement) positions.push_back(e.name);
  }
  mode.output_names = p.texts("outputs", {});
  if (!p.has("outputs")) p.fail("outputs", "name each command element of this mode, e.g. [iq_a, iq_b, iq_c]");
  std::vector<std::string> units = p.texts("output_units", {});
  const std::string plant = p.choice("plant", {"continuous", "discrete"}, std::string_view("continuous"));
  mode.continuous = plant == "continuous";
  const std::vector<double> a_values = p.numbers("A", std::vector<double>{});
  const std::vector<double> b_values = p.numbers("B", std::vector<double>{});
  const std::vector<double> acceleration = p.numbers("input_acceleration", std::vector<double>{});
  const std::vector<double> q_values = p.numbers("Q");
  const std::vector<double> r_values = p.numbers("R", std::vector<double>{});
  const std::vector<double> limits = p.numbers("output_limit", std::vector<double>{0.0});
  const std::vector<double> offsets = p.numbers("output_offset", std::vector<double>{0.0});

  // Positions: names of measurement elements, each in one mode only.
  const std::size_t np = positions.size();
  const std::size_t m = mode.output_names.size();
  if (np == 0 || np > static_cast<std::size_t>(kMaxPositions)) {
    p.fail("positions", "1 to " + count_text(kMaxPositions) + " positions per mode, got " + count_text(np));
    return;
  }
  if (m == 0 || m > static_cast<std::size_t>(kMaxInputs)) {
    p.fail("outputs", "1 to " + count_text(kMaxInputs) + " outputs per mode, got " + count_text(m));
    return;
  }
  for (std::size_t i = 0; i < np; ++i) {
    const auto found = std::find_if(measurement.begin(), measurement.end(),
                                    [&](const Element& e) { return e.name == positions[i]; });
    if (found == measurement.end()) {
      std::string names;
      for (const Element& e : measurement) names += (names.empty() ? "" : ", ") + e.name;
      p.fail("positions", "'" + positions[i] + "' is not a measurement element (" + names + ")");
      continue;
    }
    if (!used_positions.insert(positions[i]).second) {
      p.fail("positions", "'" + positions[i] + "' is controlled by another mode already");
    }
    mode.position_index[i] = static_cast<std::size_t>(found - measurement.begin());
  }
  mode.position_names = positions;
  if (units.size() == 1 && m > 1) units.assign(m, units.front());
  if (units.size() != m) {
    p.fail("output_units", "expected one SI unit or " + count_text(m) + " (one per output), got " +
                               count_text(units.size()));
    units.assign(m, "1");
  }
  mode.output_units = units;

  // Plant [pos; vel].
  const auto p2 = static_cast<Eigen::Index>(2 * np);
  const auto mi = static_cast<Eigen::Index>(m);
  Matrix A = Matrix::Zero(p2, p2);
  if (!a_values.empty()) {
    if (a_values.size() != static_cast<std::size_t>(p2 * p2)) {
      p.fail("A", "expected " + count_text(static_cast<std::size_t>(p2 * p2)) +
                      " numbers (2p x 2p, row-major, state [positions; velocities]), got " +
                      count_text(a_values.size()));
    } else {
      A = row_major(a_values, p2, p2);
    }
  } else if (mode.continuous) {
    A.topRightCorner(p2 / 2, p2 / 2) = Matrix::Identity(p2 / 2, p2 / 2);  // free masses: pos' = vel
  } else {
    p.fail("A", "plant: discrete needs A (2p x 2p at the block period)");
  }
  Matrix B = Matrix::Zero(p2, mi);
  if (!b_values.empty() == !acceleration.empty()) {
    p.fail("B", "give exactly one of B (2p x m) or input_acceleration (p x m, continuous: B = [0; it])");
  } else if (!b_values.empty()) {
    if (b_values.size() != static_cast<std::size_t>(p2 * mi)) {
      p.fail("B", "expected " + count_text(static_cast<std::size_t>(p2 * mi)) + " numbers (2p x m, row-major), got " +
                      count_text(b_values.size()));
    } else {
      B = row_major(b_values, p2, mi);
    }
  } else if (!mode.continuous) {
    p.fail("input_acceleration", "input_acceleration describes a continuous plant; with plant: discrete give B");
  } else if (acceleration.size() != np * m) {
    p.fail("input_acceleration", "expected " + count_text(np * m) + " numbers (p x m, row-major), got " +
                                     count_text(acceleration.size()));
  } else {
    B.bottomRows(p2 / 2) = row_major(acceleration, p2 / 2, mi);
  }
  if (!A.allFinite() || !B.allFinite()) p.fail("plant matrices must be finite");

  const Matrix Q = weight(p, "Q", q_values, 3 * p2 / 2, "Q ([positions, integrals, velocities])");
  const Matrix R = r_values.empty() ? Matrix(Matrix::Identity(mi, mi)) : weight(p, "R", r_values, mi, "R");

  const std::vector<double> limit = per_output(p, "output_limit", limits, m);
  const std::vector<double> offset = per_output(p, "output_offset", offsets, m);
  for (std::size_t j = 0; j < m; ++j) {
    if (!(limit[j] >= 0.0) || !std::isfinite(limit[j])) {
      p.fail("output_limit", "|u| limits must be finite and >= 0 (0: no limit), got " + number_text(limit[j]));
    }
    mode.limit[j] = limit[j];
    mode.offset[j] = offset[j];
  }
  if (!p.ok()) return;

  Expected<lq_integral::Design> d = lq_integral::design(A, B, mode.continuous, period_s, Q, R);
  if (!d) {
    p.fail(d.error());
    return;
  }
  mode.design = std::move(*d);
  mode.positions = static_cast<int>(np);
  mode.inputs = static_cast<int>(m);
  mode.K = mode.design.K;
}

}  // namespace

Status LqIntegralController::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  period_s_ = ctx.period_s();
  anti_windup_ = params.flag("anti_windup", true);
  std::vector<Params> mode_params = params.items("modes");

  ctx.declare_input(measurement_, "measurement", {}, true);
  ctx.declare_input(velocity_, "velocity", {}, false);
  ctx.declare_input(reference_, "reference", {}, false);
  const Elements* source = ctx.input_source("measurement");
  if (source == nullptr) {
    params.fail("inputs",
                "the measurement input must be connected to a configured block's output: its element names "
                "select each mode's positions");
    return Status::error("invalid parameters");
  }
  measurement_elements_ = *source;
  measurement_size_ = source->size();
  if (const Elements* velocity = ctx.input_source("velocity"); velocity != nullptr) {
    if (velocity->size() != measurement_size_) {
      params.fail("inputs", "the velocity must have one element per measurement element (" +
                                count_text(measurement_size_) + "), got " + count_text(velocity->size()));
    } else {
      for (std::size_t i = 0; i < measurement_size_; ++i) {
        const std::string expected = measurement_elements_[i].unit + "/s";
        if (!units_compatible((*velocity)[i].unit, expected)) {
          params.fail("inputs", "velocity element '" + (*velocity)[i].name + "' is in '" + (*velocity)[i].unit +
                                    "', expected '" + expected + "'");
        }
      }
    }
  }
  if (const Elements* reference = ctx.input_source("reference"); reference != nullptr) {
    if (reference->size() != measurement_size_) {
      params.fail("inputs", "the reference must have one element per measurement element (" +
                                count_text(measurement_size_) + "), got " + count_text(reference->size()));
    } else {
      for (std::size_t i = 0; i < measurement_size_; ++i) {
        if (canonical_unit((*reference)[i].unit) != canonical_unit(measurement_elements_[i].unit)) {
          params.fail("inputs", "reference element '" + (*reference)[i].name + "' is in '" + (*reference)[i].unit +
                                    "' but the measurement '" + measurement_elements_[i].name + "' is in '" +
                                    measurement_elements_[i].unit + "'");
        }
      }
    }
  }
  if (mode_params.size() > kMaxModes) {
    params.fail("modes", "at most " + count_text(kMaxModes) + " modes, got " + count_text(mode_params.size()));
    return Status::error("invalid parameters");
  }

  modes_.resize(mode_params.size());
  std::set<std::string> used_positions;
  for (std::size_t i = 0; i < mode_params.size(); ++i) {
    read_mode(mode_params[i], i, mode_params.size(), measurement_elements_, used_positions, period_s_, modes_[i]);
  }
  std::set<std::string> output_names;
  for (const Mode& mode : modes_) {
    for (const std::string& name : mode.output_names) {
      if (name.empty() || !output_names.insert(name).second) {
        params.fail("modes", "output names must be unique and non-empty across modes ('" + name + "')");
      }
    }
  }
  if (!params.ok()) return Status::error("invalid parameters");

  Elements command;
  Elements integral;
  for (Mode& mode : modes_) {
    mode.command_offset = command.size();
    mode.integral_offset = integral.size();
    for (int j = 0; j < mode.inputs; ++j) {
      command.push_back({mode.output_names[static_cast<std::size_t>(j)], mode.output_units[static_cast<std::size_t>(j)]});
    }
    for (int i = 0; i < mode.positions; ++i) {
      const Element& e = measurement_elements_[mode.position_index[static_cast<std::size_t>(i)]];
      integral.push_back({"int_" + e.name, e.unit + "*s"});
    }
  }
  command_size_ = command.size();
  integral_size_ = integral.size();
  ctx.declare_output(command_, "command", command);
  ctx.declare_output(integral_, "integral", integral);
  return params.ok() ? Status::ok() : Status::error("invalid parameters");
}

Status LqIntegralController::activate() {
  if (measurement_.size() != measurement_size_) {
    return Status::error("controller.lq_integral: the measurement has " + count_text(measurement_.size()) +
                         " elements, expected " + count_text(measurement_size_));
  }
  if (velocity_.connected() && velocity_.size() != measurement_size_) {
    return Status::error("controller.lq_integral: the velocity has " + count_text(velocity_.size()) +
                         " elements, expected " + count_text(measurement_size_));
  }
  if (reference_.connected() && reference_.size() != measurement_size_) {
    return Status::error("controller.lq_integral: the reference has " + count_text(reference_.size()) +
                         " elements, expected " + count_text(measurement_size_));
  }
  for (Mode& mode : modes_) {
    mode.integral.fill(0.0);
    mode.previous_position.fill(0.0);
    mode.saturated = false;
    for (int j = 0; j < mode.inputs; ++j) command_[mode.command_offset + static_cast<std::size_t>(j)] = 0.0;
  }
  for (std::size_t i = 0; i < integral_size_; ++i) integral_[i] = 0.0;
  have_previous_ = false;
  return Status::ok();
}

StepStatus LqIntegralController::step(const Tick& /*tick*/) noexcept {
  // Inputs first, so a fault leaves every mode as it was.
  for (std::size_t i = 0; i < measurement_size_; ++i) {
    if (!std::isfinite(measurement_[i])) return fault("non-finite measurement");
    if (velocity_.connected() && !std::isfinite(velocity_[i])) return fault("non-finite velocity");
    if (reference_.connected() && !std::isfinite(reference_[i])) return fault("non-finite reference");
  }
  for (Mode& mode : modes_) {
    const int p = mode.positions;
    std::array<double, lq_integral::kMaxStates> xi{};  // [pos - pos*; z; vel]
    for (int i = 0; i < p; ++i) {
      const std::size_t index = mode.position_index[static_cast<std::size_t>(i)];
      const double position = measurement_[index];
      xi[static_cast<std::size_t>(i)] = position - (reference_.connected() ? reference_[index] : 0.0);
      xi[static_cast<std::size_t>(p + i)] = mode.integral[static_cast<std::size_t>(i)];
      double velocity = 0.0;
      if (velocity_.connected()) {
        velocity = velocity_[index];
      } else if (have_previous_) {
        velocity = (position - mode.previous_position[static_cast<std::size_t>(i)]) / period_s_;
      }
      xi[static_cast<std::size_t>(2 * p + i)] = velocity;
    }

    // u = u* - K xi (eq. 10); clamp; hold the integrators while they push into a clamp.
    bool hold_integrators = false;
    std::array<double, kMaxInputs> u{};
    for (int j = 0; j < mode.inputs; ++j) {
      double value = mode.offset[static_cast<std::size_t>(j)];
      for (int k = 0; k < 3 * p; ++k) value -= mode.K(j, k) * xi[static_cast<std::size_t>(k)];
      if (!std::isfinite(value)) return fault("non-finite LQ command");
      const double limit = mode.limit[static_cast<std::size_t>(j)];
      if (limit > 0.0 && std::abs(value) > limit) {
        const double direction = value > 0.0 ? 1.0 : -1.0;
        value = direction * limit;
        double integrator_push = 0.0;  // change of u_j that this cycle's integration would cause
        for (int i = 0; i < p; ++i) {
          integrator_push -= mode.K(j, p + i) * period_s_ * xi[static_cast<std::size_t>(i)];
        }
        if (anti_windup_ && integrator_push * direction > 0.0) hold_integrators = true;
      }
      u[static_cast<std::size_t>(j)] = value;
    }
    mode.saturated = hold_integrators;
    for (int j = 0; j < mode.inputs; ++j) {
      command_[mode.command_offset + static_cast<std::size_t>(j)] = u[static_cast<std::size_t>(j)];
    }
    for (int i = 0; i < p; ++i) {
      const auto s = static_cast<std::size_t>(i);
      if (!hold_integrators) mode.integral[s] += period_s_ * xi[s];  // z_{k+1} = z_k + T e_k
      mode.previous_position[s] = measurement_[mode.position_index[s]];
      integral_[mode.integral_offset + s] = mode.integral[s];
    }
  }
  have_previous_ = true;
  return StepStatus::ok;
}

void LqIntegralController::describe(Json& out) const {
  out["period_s"] = period_s_;
  out["law"] = "u = u* - K xi, xi = [pos - pos*; z; vel], z_{k+1} = z_k + T (pos_k - pos*_k) (eqs. 10, 14)";
  out["velocity_source"] = velocity_.connected() ? "velocity input"
                                                 : "velocity input if connected, else (pos_k - pos_{k-1}) / T";
  out["anti_windup"] = anti_windup_ ? "clamp |u_j| to output_limit; hold the mode's integrators while their "
                                      "increment pushes a clamped output further into its limit"
                                    : "off (outputs are clamped, integrators always run)";
  Json modes = Json::array();
  for (const Mode& mode : modes_) {
    const lq_integral::Design& d = mode.design;
    Json m = Json::object();
    m["name"] = mode.name;
    m["positions"] = text_list(mode.position_names);
    m["outputs"] = text_list(mode.output_names);
    m["output_units"] = text_list(mode.output_units);
    m["plant"] = mode.continuous ? "continuous, zero-order hold at the block period" : "discrete at the block period";
    std::vector<std::string> columns;
    for (const std::string& name : mode.position_names) columns.push_back(name);
    for (const std::string& name : mode.position_names) columns.push_back("int_" + name);
    for (const std::string& name : mode.position_names) columns.push_back(name + "_dot");
    m["state_order"] = text_list(columns);
    m["plant_A_discrete"] = matrix_json(d.plant_A);
    m["plant_B_discrete"] = matrix_json(d.plant_B);
    m["Phi"] = matrix_json(d.Phi);
    m["Gamma"] = matrix_json(d.Gamma);
    m["Q"] = matrix_json(d.Q);
    m["R"] = matrix_json(d.R);
    m["K"] = matrix_json(d.K);
    m["riccati_relative_residual"] = d.riccati_residual;
    std::vector<double> limits;
    std::vector<double> offsets;
    for (int j = 0; j < mode.inputs; ++j) {
      limits.push_back(mode.limit[static_cast<std::size_t>(j)]);
      offsets.push_back(mode.offset[static_cast<std::size_t>(j)]);
    }
    m["output_limit"] = limits;
    m["output_offset"] = offsets;
    Json poles = Json::array();
    double slowest_hz = 0.0;
    double fastest_hz = 0.0;
    double largest_abs = 0.0;
    for (Eigen::Index i = 0; i < d.closed_loop_poles.size(); ++i) {
      const std::complex<double> z = d.closed_loop_poles(i);
      const std::complex<double> s = std::log(z) / period_s_;  // equivalent continuous pole
      const double natural_hz = std::abs(s) / (2.0 * std::numbers::pi);
      Json pole = Json::object();
      pole["re"] = z.real();
      pole["im"] = z.imag();
      pole["abs"] = std::abs(z);
      pole["natural_hz"] = natural_hz;
      pole["damping"] = std::abs(s) > 0.0 ? -s.real() / std::abs(s) : 1.0;
      poles.push(std::move(pole));
      slowest_hz = i == 0 ? natural_hz : std::min(slowest_hz, natural_hz);
      fastest_hz = std::max(fastest_hz, natural_hz);
      largest_abs = std::max(largest_abs, std::abs(z));
    }
    m["closed_loop_poles"] = std::move(poles);
    m["largest_pole_abs"] = largest_abs;
    m["pole_natural_hz_range"] = std::vector<double>{slowest_hz, fastest_hz};
    m["bandwidth_hz"] = d.bandwidth_hz;
    m["bandwidth_definition"] = "-3 dB of the closed loop pos_i / pos*_i per position (0: none below Nyquist)";
    modes.push(std::move(m));
  }
  out["modes"] = std::move(modes);
}

namespace {

constexpr ParamDoc kParams[] = {
    {"modes", "list<map>", nullptr,
     "one 3p-state design per mode: {name, positions: [measurement names] (default all, one mode), "
     "outputs: [names], output_units: unit|[units], plant: continuous|discrete (default continuous), "
     "A: 2p x 2p row-major over [positions; velocities] (default free masses; required if discrete), "
     "B: 2p x m row-major | input_acceleration: p x m (continuous, B = [0; it]), "
     "Q: 3p diagonal or (3p)^2 row-major in [positions, integrals, velocities] order, "
     "R: m diagonal or m^2 (default I), output_limit: |u| clamp, one or m (0 = none), "
     "output_offset: u*, one or m (default 0)}"},
    {"anti_windup", "bool", "true",
     "hold a mode's integrators while their increment pushes a clamped output further into output_limit"},
};

constexpr PortSpec kPorts[] = {
    {"measurement", PortDirection::in, "n measured positions (names select each mode's positions), e.g. notch.out"},
    {"velocity", PortDirection::in, "optional n velocities [<unit>/s] (e.g. kf.velocity); else backward difference"},
    {"reference", PortDirection::in, "optional n references in the measurement's units; 0 when not connected"},
    {"command", PortDirection::out, "every mode's outputs u = u* - K xi, in output_units"},
    {"integral", PortDirection::out, "the integrator states z, int_<name> [<unit>*s]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::LqIntegralController, "controller.lq_integral", lode::PluginKind::controller, "0.1.0",
            "Integrator-augmented discrete LQ per mode, [position, integral, velocity] state (Silva-Rivas & Kim 2013)",
            lode::plugins::kParams, lode::plugins::kPorts)
