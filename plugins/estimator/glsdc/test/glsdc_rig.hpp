// The estimator.glsdc test rig shared by the plugin's test files: a configured block behind the
// BlockHarness, the halbach_hall "truth" that makes its measurements (thesis geometry, with
// positions assumed since the thesis shows them only in Fig. 28: A = (+6.35, +95.25) mm,
// B = (-6.35, -95.25) mm, 2 mm gap) and the set-ups the tests share.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "estimator/testing/harness_setup.hpp"
#include "glsdc.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins::glsdc_testing {

using lode::testing::BlockHarness;

constexpr double kRateHz = 800.0;
constexpr double kPitch = 0.0508;
constexpr double kQuarterPitch = kPitch / 4.0;

/// Two sensors half a pitch apart in x and y: at x = y = l/4 both sit at a field extremum,
/// where every slope of harmonics [1, 5] vanishes (cos(pi/2) = cos(5 pi/2) = 0) and H'WH has
/// zero x and y columns.
inline const std::string kFieldExtremumModels =
    "hall:\n  plugin: sensor.halbach_hall\n  sensors:\n"
    "    - {name: A, x_m: 0.0, y_m: 0.0, channels: [a1, b1]}\n"
    "    - {name: B, x_m: 0.0254, y_m: 0.0254, channels: [c1, d2]}\n";

/// A `models:` map with one halbach_hall model named `name`. The three-sensor configuration
/// adds C = (+95.25, +6.35) mm: sensor A turned by 90 degrees about the centre of mass, so that
/// a rotation moves C in world Y (seen by its a channel) as much as it moves A and B in world X.
/// (The thesis's C position is only in its missing Figs. 54-55; C = (0, 0) adds no lever arm.)
inline std::string hall_model(const std::string& name, const std::string& harmonics, bool sensor_c = false) {
  std::string s = name + ":\n"
                  "  plugin: sensor.halbach_hall\n"
                  "  harmonics: " + harmonics + "\n"
                  "  sensors:\n"
                  "    - {name: A, x_m: 0.00635, y_m: 0.09525, channels: [a1, b1]}\n"
                  "    - {name: B, x_m: -0.00635, y_m: -0.09525, channels: [c1, d2]}\n";
  if (sensor_c) s += "    - {name: C, x_m: 0.09525, y_m: 0.00635, channels: [a2, b2]}\n";
  return s;
}

inline Elements channel_elements(bool sensor_c) {
  Elements e = {{"a1", "V"}, {"b1", "V"}, {"c1", "V"}, {"d2", "V"}};
  if (sensor_c) {
    e.push_back({"a2", "V"});
    e.push_back({"b2", "V"});
  }
  return e;
}

/// One configured and activated estimator.glsdc block.
class Rig {
 public:
  Rig(const std::string& params, const std::string& models, bool sensor_c = false,
      bool theta_input = false)
      : h_("estimator.glsdc", params, kRateHz, models), channels_(sensor_c ? 6 : 4) {
    h_.feed("measurement", channel_elements(sensor_c));
    if (theta_input) h_.feed("theta", {{"theta_z", "rad"}});
    const Status s = h_.configure();
    ok_ = s.is_ok();
    if (!ok_) {
      ADD_FAILURE() << h_.diagnostics();
      return;
    }
    EXPECT_TRUE(h_.activate().is_ok());
    block_ = dynamic_cast<Glsdc*>(&h_.block());
    EXPECT_NE(block_, nullptr);
  }

  [[nodiscard]] bool ok() const { return ok_ && block_ != nullptr; }
  Glsdc& block() { return *block_; }
  lode::EstimatorState& estimator() { return *block_; }
  const MeasurementModel& model() { return *block_->model(); }
  BlockHarness& harness() { return h_; }

  /// Feed one measurement and run one tick.
  StepStatus step(const std::vector<double>& y) {
    auto in = h_.input("measurement");
    std::copy(y.begin(), y.end(), in.begin());
    return h_.step();
  }
  void set_theta(double theta) { h_.input("theta")[0] = theta; }
  [[nodiscard]] double pose(int i) const { return h_.output("pose")[static_cast<std::size_t>(i)]; }
  [[nodiscard]] double covariance(int i, int j) const {
    return h_.output("covariance")[static_cast<std::size_t>(3 * i + j)];
  }
  [[nodiscard]] double cost() const { return h_.output("cost")[0]; }
  [[nodiscard]] std::size_t channels() const { return channels_; }

 private:
  BlockHarness h_;
  std::size_t channels_;
  bool ok_ = false;
  Glsdc* block_ = nullptr;
};

/// The "truth": a halbach_hall model instance obtained through its own (unused) estimator.
class Truth {
 public:
  explicit Truth(const std::string& harmonics, bool sensor_c = false)
      : rig_("model: truth", hall_model("truth", harmonics, sensor_c), sensor_c) {}
  [[nodiscard]] bool ok() const { return rig_.ok(); }
  std::vector<double> measure(double x, double y, double theta) {
    std::vector<double> out(rig_.channels());
    const double state[3] = {x, y, theta};
    rig_.model().evaluate(state, out.data());
    return out;
  }

 private:
  Rig rig_;
};

inline std::string params_with_initial(double x, double y, double theta, const std::string& extra = "") {
  char buffer[160];
  std::snprintf(buffer, sizeof buffer, "model: hall\ninitial: [%.17g, %.17g, %.17g]\n", x, y, theta);
  return buffer + extra;
}

/// The plain set-up: estimator.glsdc with its defaults over the [1, 5] hall model, measured by a
/// truth of that same model.
struct HallSetup {
  Truth truth{"[1, 5]"};
  Rig rig{"model: hall", hall_model("hall", "[1, 5]")};
  [[nodiscard]] bool ok() const { return truth.ok() && rig.ok(); }
};

/// The heap allocations of `ticks` ticks of `rig`, fed `measurements` in turn, each tick
/// followed by `after_tick()` (LODE_REQUIRE_ALLOCATION_COUNTING() first).
template <typename AfterTick>
std::size_t allocations_over_ticks(Rig& rig, const std::vector<std::vector<double>>& measurements, int ticks,
                                   AfterTick&& after_tick) {
  auto in = rig.harness().input("measurement");
  return estimator_testing::allocations_during([&] {
    for (int k = 0; k < ticks; ++k) {
      const std::vector<double>& y = measurements[static_cast<std::size_t>(k) % measurements.size()];
      std::copy(y.begin(), y.end(), in.begin());
      rig.harness().step();
      after_tick();
    }
  });
}

}  // namespace lode::plugins::glsdc_testing
