// Optional interface: an estimator's state and innovation (hot swap, health monitor, shadows).
//
// A block that estimates a state derives from EstimatorState beside Block, so that a
// replacement can warm-start from it at the cycle boundary of a hot swap, and reports its
// innovation so the health monitor and the shadow statistics can test it. The state exported
// is the prior of the coming step(): for a Kalman filter x⁻_k and P⁻_k, for GLSDC the
// warm-start pose.
//
// state_layout() is called off the RT thread after configure(); export_state(),
// import_state() and innovation() on the RT thread between steps: RT-safe, no allocation,
// sizes fixed by the layout.
#pragma once

#include <cstddef>
#include <cstdint>

#include "lode/sdk/port.hpp"

namespace lode {

/// What an estimator's exported state holds (see Block::state_layout()).
struct StateLayout {
  Elements elements;        ///< name and SI unit of each state element, in export order
  bool covariance = false;  ///< export_state() also writes the n x n covariance
  [[nodiscard]] std::size_t size() const { return elements.size(); }
  [[nodiscard]] bool empty() const { return elements.empty(); }
};

class EstimatorState {
 public:
  virtual ~EstimatorState();
  /// Named elements with units (e.g. x, x_dot, x_ddot, y, ... in m, m/s, m/s^2); empty
  /// when the block has no exportable state.
  [[nodiscard]] virtual StateLayout state_layout() const = 0;
  /// Write n = layout size values and, when layout.covariance, n*n row-major covariance.
  virtual void export_state(double* values, double* covariance) const noexcept = 0;
  /// Take the state from `values` where present[i] != 0; keep the block's own initial
  /// value (after activate()) for the others. `covariance` (n*n, may be nullptr) gives
  /// P(i,j) for pairs where both are present; rows and columns of absent elements keep the
  /// block's own initial covariance with zero cross terms. Must leave a usable filter
  /// (symmetric positive definite P) whatever it is given; a block may symmetrise. By
  /// default a block takes nothing and starts from its own initial state.
  virtual void import_state(const double* /*values*/, const double* /*covariance*/,
                            const std::uint8_t* /*present*/) noexcept {}
  /// Channels of the measurement update (0 = none): size of innovation()'s arrays.
  [[nodiscard]] virtual std::size_t innovation_size() const { return 0; }
  /// The last step's innovation nu = y - y_hat and its predicted variance S(i,i) (the
  /// diagonal of H P⁻ H' + R). False when the last step made no measurement update
  /// (coasting, first cycle). NIS (diagonal) = sum nu_i^2 / S(i,i).
  virtual bool innovation(double* /*residual*/, double* /*variance*/) const noexcept { return false; }
};

}  // namespace lode
