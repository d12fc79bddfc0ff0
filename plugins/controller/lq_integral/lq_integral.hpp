// controller.lq_integral: integrator-augmented discrete LQ state feedback, one 3p-state design
// per mode (Silva-Rivas & Kim 2013, eqs. 8-19).
//
// @system
// name: controller.lq_integral
// input_ports:
//   measurement: n elements, any names/units             # e.g. notch.out: x [m], y [m], phi [rad]
//   velocity:    n elements, optional, <unit>/s          # e.g. kf.velocity; else backward difference
//   reference:   n elements, optional, measurement units # 0 when not connected
// output_ports:
//   command:  sum of the modes' outputs, named and united by each mode's outputs/output_units
//   integral: sum of the modes' positions, int_<name> [<unit>*s]   # the integrator states
// @endsystem
//
// Per mode (p positions, m inputs), the plant x = [pos; vel] (2p states) is
//   continuous  x' = A x + B u, discretised by zero-order hold at the block period T, or
//   discrete    x_{k+1} = A x_k + B u_k at T,
// and is augmented with the output-error integrator of eq. 14, discretised as in the inverse
// fit of plant.maglev6's surrogate B:  z_{k+1} = z_k + T (pos_k - pos*_k).  The augmented state,
// in the order of the printed Q and K (eq. 14 writes [x; z], velocities before integrals), is
// xi = [pos - pos*; z; vel]  (3p states):
//   xi_{k+1} = Phi xi_k + Gamma u_k,   Phi = [[A_pp, 0, A_pv], [T I, I, 0], [A_vp, 0, A_vv]],
//   Gamma = [B_p; 0; B_v],
// and the gain minimises sum xi'Q xi + u'R u (discrete DARE, lode::math::dlqr):
//   u_k = u* - K xi_k                                                   (eq. 10, Delta u = -K xi)
// References enter only through the error coordinates (no feedforward, eqs. 8-10). Velocities
// come from the velocity input (an observer's estimate) or, when it is not connected, from the
// backward difference (pos_k - pos_{k-1})/T (the paper does not say what its "LQ alone" runs used).
// Anti-windup (not in the paper): with output_limit set, each |u_j| is clamped, and while
// any clamped output would be pushed further into its limit by this cycle's integrator
// increment (-K_int T e), the integrators of the mode hold (conditional integration).
//
// Threads: configure()/activate()/describe() on the loader thread, step() on the RT thread.
#pragma once

#include <Eigen/Core>
#include <array>
#include <complex>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/math/riccati.hpp"

namespace lode::plugins {

namespace lq_integral {

inline constexpr std::size_t kMaxModes = 4;
inline constexpr int kMaxPositions = 6;                 ///< p per mode
inline constexpr int kMaxInputs = 6;                    ///< m per mode
inline constexpr int kMaxStates = 3 * kMaxPositions;    ///< 3p: [pos, int, vel]

/// The configure-time design of one mode.
struct Design {
  double period_s = 0.0;
  lode::math::Matrix plant_A;  ///< discrete [pos; vel] model at T (2p x 2p)
  lode::math::Matrix plant_B;  ///< (2p x m)
  lode::math::Matrix Phi;      ///< augmented [pos, int, vel] (3p x 3p)
  lode::math::Matrix Gamma;    ///< (3p x m)
  lode::math::Matrix Q;        ///< (3p x 3p)
  lode::math::Matrix R;        ///< (m x m)
  lode::math::Matrix K;        ///< (m x 3p), u = u* - K xi
  Eigen::VectorXcd closed_loop_poles;  ///< eigenvalues of Phi - Gamma K
  double riccati_residual = 0.0;       ///< lode::math::DareSolution::relative_residual
  /// -3 dB frequency of pos_i / pos*_i of the closed loop, per position [Hz]; 0 if the
  /// magnitude never falls below 1/sqrt(2) before Nyquist.
  std::vector<double> bandwidth_hz;
};

/// Builds Phi, Gamma from the [pos; vel] plant (continuous: ZOH at T) and solves the DARE.
/// A: 2p x 2p, B: 2p x m, Q: 3p x 3p in [pos, int, vel] order, R: m x m.
Expected<Design> design(const lode::math::Matrix& A, const lode::math::Matrix& B, bool continuous,
                        double period_s, const lode::math::Matrix& Q, const lode::math::Matrix& R);

/// The real-time part of one mode.
struct Mode {
  std::string name;
  std::vector<std::string> position_names;
  std::vector<std::string> output_names;
  std::vector<std::string> output_units;
  bool continuous = true;
  Design design;

  int positions = 0;  ///< p
  int inputs = 0;     ///< m
  std::array<std::size_t, kMaxPositions> position_index{};  ///< into the measurement
  std::size_t command_offset = 0;                           ///< first command element
  std::size_t integral_offset = 0;                          ///< first integral element
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxInputs, kMaxStates> K;
  std::array<double, kMaxInputs> offset{};  ///< u*
  std::array<double, kMaxInputs> limit{};   ///< |u| clamp, 0: none
  std::array<double, kMaxPositions> integral{};
  std::array<double, kMaxPositions> previous_position{};
  bool saturated = false;
};

}  // namespace lq_integral

class LqIntegralController final : public Block {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  double period_s_ = 0.0;
  bool anti_windup_ = true;
  bool have_previous_ = false;  ///< a previous measurement exists for the backward difference
  std::size_t measurement_size_ = 0;
  std::size_t command_size_ = 0;
  std::size_t integral_size_ = 0;
  std::vector<lq_integral::Mode> modes_;  ///< sized in configure()
  Elements measurement_elements_;

  InputPort measurement_;
  InputPort velocity_;
  InputPort reference_;
  OutputPort command_;
  OutputPort integral_;
};

}  // namespace lode::plugins
