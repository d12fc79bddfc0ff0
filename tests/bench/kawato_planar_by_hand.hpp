// kawato_planar's cycle written out by hand, the way one would code it without lodestone: the
// simulated platen and its Hall sensors, the GLSDC, the three per-axis Kalman filters, the step
// reference and the three lead-lag controllers, called directly in the pipeline's order on
// plain arrays. No pipeline, ports, plugin virtual calls, envelope or hooks: the baseline
// lode_framework_overhead_bench measures the framework against.
//
// It calls the kernels the plugins run (PlanarStage, HalbachHall, kalman::AxisFilter,
// discrete_tf::Section, the io.sim converter chain), configured with kawato_planar.yaml's
// values written here as constants, as a hand-written controller would have them. The GLSDC is
// the plugin's own solver (Glsdc::step, called directly on the concrete class, not through
// the Block interface), so that whatever makes it faster shows in both columns; it reads the
// measurement from, and writes its pose and covariance to, plain arrays that a loaded pipeline
// lends it, because that is where its input and outputs point.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "discrete_tf.hpp"
#include "glsdc.hpp"
#include "halbach_hall.hpp"
#include "kalman.hpp"
#include "lode/pipeline.hpp"
#include "planar_stage.hpp"
#include "sim_converter.hpp"

namespace lode::bench {

class KawatoPlanarByHand {
 public:
  static constexpr double kRateHz = 800.0;

  /// `lender`: a loaded, activated kawato_planar pipeline that nothing else runs; its GLSDC
  /// instance and the storage of that block's input and outputs are used (see above).
  explicit KawatoPlanarByHand(Pipeline& lender);

  /// Empty when the constructor succeeded, else why not.
  [[nodiscard]] const std::string& error() const { return error_; }

  /// One cycle, `cycle` counting from 0. False on a non-finite value anywhere (a fault).
  bool cycle(std::uint64_t cycle) noexcept;

  /// Every output this computes, by the pipeline's name for it ("kf.pose"), with its size.
  struct Output {
    const double* data = nullptr;
    std::size_t size = 0;
  };
  [[nodiscard]] const std::map<std::string, Output>& outputs() const { return outputs_; }

 private:
  static constexpr std::size_t kChannels = 4;
  static constexpr std::size_t kAxes = 3;

  std::string error_;
  std::map<std::string, Output> outputs_;

  // io.sim "stage": the platen, the true field, the converter.
  plugins::PlanarStage plant_;
  plugins::HalbachHall field_;
  plugins::sim::GaussianNoise noise_;
  plugins::sim::ConverterScale converter_;
  std::array<double, 3> truth_{};
  std::array<double, plugins::PlanarStage::kStateSize> plant_state_{};
  std::array<double, kChannels> counts_{};
  std::array<double, kChannels> clean_{};
  double* signals_ = nullptr;  ///< the GLSDC's measurement input

  // estimator.glsdc
  plugins::Glsdc* glsdc_ = nullptr;
  const double* glsdc_pose_ = nullptr;
  const double* glsdc_covariance_ = nullptr;

  // estimator.kalman "kf"
  std::array<plugins::kalman::AxisFilter<3>, kAxes> filters_;
  std::array<bool, kAxes> start_at_measurement_{};
  std::array<double, kAxes> kf_pose_{}, kf_velocity_{}, kf_acceleration_{}, kf_innovation_{};

  // source.step "ref"
  std::array<double, kAxes> reference_{};

  // controller.discrete_tf "ctrl"
  std::array<plugins::discrete_tf::Section, kAxes> controllers_;
  std::array<double, kAxes> command_{};
};

}  // namespace lode::bench
