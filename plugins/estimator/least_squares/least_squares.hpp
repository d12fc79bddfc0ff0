// estimator.least_squares: a pose from the signals of one or more measurement models by
// weighted Gauss-Newton, warm-started every tick.
//
// The GLSDC of estimator.glsdc generalised to any MeasurementModel and to several models at
// once: the state is the union of the models' state elements (a name shared by two models
// is one state), the channels are the models' channels concatenated in the order of
// `models` (the order io.sim concatenates them with the same `sensors` list). Silva-Rivas &
// Kim (2013) feed their notch and hybrid filter a 6-DOF pose from the Hall sensors (x, y, phi)
// and the lasers (z, theta, psi) without giving the conversion; this block computes it.
//
// @system
// name: estimator.least_squares
// input_ports:
//   measurement: [every model's channels, in `models` order]     # e.g. A_a, A_b, ..., L1, L2, L3 [V]
// output_ports:
//   pose: [union of the models' state elements, first appearance] # e.g. x, y, theta_z, z, theta_x, theta_y
//   cost: [cost: 1]                                               # J = |y - h(z)|^2_W at the published pose
// @endsystem
//
// Per tick, `iterations` times (warm start: z from the previous tick):
//   f = h(z), H = dh/dz (stacked over the models, each model's columns scattered to its states)
//   dz = (H' W H)^-1 H' W (y - f),   z <- z + dz,   W = diag(1 / noise_std_v^2)
// With models that are linear in the state (sensor.laser_gap at small angles) one iteration
// is the exact least-squares solution; for the Hall field model it is the thesis's one
// Gauss-Newton step per sample (Kawato 2005, Appendix B/C), which converges as long as the
// pose moves much less than a quarter pitch per tick.
//
// Threads: configure()/activate()/describe() on the loader thread; step() on the RT thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Cholesky>
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"

namespace lode::plugins {

class LeastSquaresPose final : public Block {
 public:
  static constexpr int kMaxStates = 12;
  static constexpr int kMaxChannels = 32;

  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;

 private:
  using NormalMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxStates, kMaxStates>;
  using StateVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxStates, 1>;

  /// One model and where its state and channels live in the union.
  struct Slot {
    std::string name;
    std::unique_ptr<MeasurementModel> model;
    std::vector<std::size_t> state_index;  ///< model state j -> union state
    std::size_t first_channel = 0;
    std::size_t channel_count = 0;
  };

  /// f = h(z) for every channel and, if jacobian is set, H (channels x states, zero-filled).
  void linearize(bool with_jacobian) noexcept;

  std::vector<Slot> slots_;
  Elements state_elements_;
  Elements channel_elements_;
  std::size_t states_ = 0;
  std::size_t channels_ = 0;
  int iterations_ = 1;
  std::vector<double> weight_;   ///< 1 / sigma^2 per channel
  std::vector<double> initial_;

  InputPort measurement_;
  OutputPort pose_;
  OutputPort cost_;

  // Cycle storage, sized in configure().
  StateVector estimate_;
  std::array<double, kMaxChannels> predicted_{};
  std::array<double, kMaxChannels * kMaxStates> jacobian_{};  ///< row-major channels x states
  std::array<double, kMaxChannels * kMaxStates> model_jacobian_{};
  std::array<double, kMaxStates> model_state_{};
  NormalMatrix normal_;
  StateVector gradient_;
  Eigen::LLT<NormalMatrix> factor_{kMaxStates};
};

}  // namespace lode::plugins
