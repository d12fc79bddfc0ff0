// estimator.least_squares through the BlockHarness: exact recovery with a linear model (one
// step), the six-axis union of sensor.halbach_hall (x, y, theta_z) and sensor.laser_gap
// (z, theta_x, theta_y) fed by io.sim with plant.maglev6, noise propagation, configuration
// errors, faults and no allocation.
#include "least_squares.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "estimator/testing/harness_setup.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins {
namespace {

using lode::estimator_testing::started;
using lode::testing::BlockHarness;

constexpr double kRateHz = 800.0;

const char* kModels = R"(
stage: {plugin: plant.maglev6}
hall:
  plugin: sensor.halbach_hall
  pitch_m: 0.05098
  gap_m: 0.0023
  sensitivity_v_per_t: 8.0
  sensors:
    - {name: A, x_m: 0.0400, y_m: 0.0}
    - {name: B, x_m: -0.0200, y_m: 0.0346}
    - {name: C, x_m: -0.0200, y_m: -0.0346}
laser:
  plugin: sensor.laser_gap
  sensitivity_v_per_m: 1.0e5
  sensors:
    - {name: L1, x_m: 0.05, y_m: 0.0}
    - {name: L2, x_m: -0.025, y_m: 0.0433}
    - {name: L3, x_m: -0.025, y_m: -0.0433}
)";

const Elements kCommand = {{"iq_a", "A"}, {"iq_b", "A"}, {"iq_c", "A"}, {"id_a", "A"}, {"id_b", "A"}, {"id_c", "A"}};
const Elements kLaserChannels = {{"L1", "V"}, {"L2", "V"}, {"L3", "V"}};

std::string board_models(const std::string& initial) {
  std::string m = kModels;
  const std::string from = "stage: {plugin: plant.maglev6}";
  m.replace(m.find(from), from.size(), "stage: {plugin: plant.maglev6, initial: " + initial + "}");
  return m;
}

TEST(LeastSquares, LinearModelIsSolvedInOneStep) {
  BlockHarness board("io.sim", "plant: stage\nsensors: laser\nadc_bits: 0\nnoise_std_v: 0", kRateHz,
                     board_models("[0, 0, 0, 3.0e-6, 20.0e-6, -15.0e-6]"));
  board.feed("command", kCommand);
  ASSERT_TRUE(started(board));
  board.step();

  BlockHarness h("estimator.least_squares", "models: laser\nnoise_std_v: 1.0e-3", kRateHz, kModels);
  h.feed("measurement", kLaserChannels);
  ASSERT_TRUE(started(h));
  const auto signals = board.output("signals");
  std::copy(signals.begin(), signals.end(), h.input("measurement").begin());
  ASSERT_EQ(h.step(), StepStatus::ok);
  ASSERT_EQ(h.output_elements("pose").size(), 3u);
  EXPECT_EQ(h.output_elements("pose")[1].name, "theta_x");
  // Small-angle linearisation error only (second order in 2e-5 rad: ~1e-12 relative).
  EXPECT_NEAR(h.output("pose")[0], 3e-6, 1e-13);
  EXPECT_NEAR(h.output("pose")[1], 20e-6, 1e-12);
  EXPECT_NEAR(h.output("pose")[2], -15e-6, 1e-12);
  h.step();  // second tick: exact
  EXPECT_NEAR(h.output("pose")[0], 3e-6, 1e-16);
  EXPECT_LT(h.output("cost")[0], 1e-18);
}

TEST(LeastSquares, SixAxisPoseFromHallAndLasers) {
  const std::string initial = "[1.2e-3, -0.8e-3, 2.0e-3, 4.0e-6, 25.0e-6, -10.0e-6]";
  BlockHarness board("io.sim", "plant: stage\nsensors: [hall, laser]\nadc_bits: 0\nnoise_std_v: 0", kRateHz,
                     board_models(initial));
  board.feed("command", kCommand);
  ASSERT_TRUE(started(board));
  board.step();

  BlockHarness h("estimator.least_squares", "models: [hall, laser]\nnoise_std_v: 1.0e-3", kRateHz, kModels);
  h.feed("measurement", board.output_elements("signals"));
  ASSERT_TRUE(started(h));
  const Elements& pose = h.output_elements("pose");
  ASSERT_EQ(pose.size(), 6u);
  const char* names[] = {"x", "y", "theta_z", "z", "theta_x", "theta_y"};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(pose[i].name, names[i]);
  // Warm start from 0: a few Gauss-Newton ticks to converge over 1-2 mm.
  const auto signals = board.output("signals");
  for (int k = 0; k < 10; ++k) {
    std::copy(signals.begin(), signals.end(), h.input("measurement").begin());
    ASSERT_EQ(h.step(), StepStatus::ok);
  }
  const auto truth = board.output("truth");
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(h.output("pose")[i], truth[i], 1e-12) << names[i];
  EXPECT_LT(h.output("cost")[0], 1e-12);
  EXPECT_NE(h.describe().dump().find("sensitivity_v_per_m"), std::string::npos);
}

TEST(LeastSquares, WhiteVoltageNoiseMapsThroughTheGeometry) {
  // Lasers at 120 degrees on a 50 mm circle: z noise = sigma / (s sqrt 3) (see laser_gap_test).
  BlockHarness board("io.sim", "plant: stage\nsensors: laser\nadc_bits: 0\nnoise_std_v: 1.0e-3\nseed: 9", kRateHz,
                     board_models("[0, 0, 0, 0, 0, 0]"));
  board.feed("command", kCommand);
  ASSERT_TRUE(started(board));
  BlockHarness h("estimator.least_squares", "models: laser\nnoise_std_v: 1.0e-3", kRateHz, kModels);
  h.feed("measurement", kLaserChannels);
  ASSERT_TRUE(started(h));
  double sum = 0.0, sum2 = 0.0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    board.step();
    const auto s = board.output("signals");
    std::copy(s.begin(), s.end(), h.input("measurement").begin());
    h.step();
    sum += h.output("pose")[0];
    sum2 += h.output("pose")[0] * h.output("pose")[0];
  }
  const double std_z = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  const double expected = 1e-3 / (1e5 * std::sqrt(3.0));
  EXPECT_NEAR(std_z, expected, 0.03 * expected);
}

TEST(LeastSquares, ConfigurationErrorsAreReported) {
  {
    BlockHarness h("estimator.least_squares", "models: [laser]\nnoise_std_v: [1, 2]\niterations: 50\ninitial: [1]",
                   kRateHz, kModels);
    h.feed("measurement", kLaserChannels);
    EXPECT_FALSE(h.configure());
    const std::string d = h.diagnostics();
    EXPECT_NE(d.find("one per channel"), std::string::npos) << d;
    EXPECT_NE(d.find("1 ... 20"), std::string::npos) << d;
    EXPECT_NE(d.find("one per state: z, theta_x, theta_y"), std::string::npos) << d;
  }
  {
    BlockHarness h("estimator.least_squares", "models: [laser]", kRateHz, kModels);
    h.feed("measurement", {{"L1", "V"}, {"L3", "V"}, {"L2", "V"}});
    EXPECT_FALSE(h.configure());
    EXPECT_NE(h.diagnostics().find("'L3'"), std::string::npos) << h.diagnostics();
  }
  {
    BlockHarness h("estimator.least_squares", "models: [nosuch]", kRateHz, kModels);
    h.feed("measurement", kLaserChannels);
    EXPECT_FALSE(h.configure());
    EXPECT_NE(h.diagnostics().find("no model named 'nosuch'"), std::string::npos) << h.diagnostics();
  }
}

TEST(LeastSquares, FaultsAndAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  BlockHarness h("estimator.least_squares", "models: [hall, laser]\nnoise_std_v: 1.0e-3\niterations: 2", kRateHz,
                 kModels);
  Elements channels = {{"A_a", "V"}, {"A_b", "V"}, {"B_a", "V"}, {"B_b", "V"}, {"C_a", "V"}, {"C_b", "V"}};
  channels.insert(channels.end(), kLaserChannels.begin(), kLaserChannels.end());
  h.feed("measurement", channels);
  ASSERT_TRUE(started(h));
  auto in = h.input("measurement");
  std::fill(in.begin(), in.end(), 0.0);
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 2000; ++k) {
    in[0] = 1e-3 * std::sin(0.01 * k);
    ASSERT_EQ(h.step(), StepStatus::ok);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  in[4] = std::nan("");
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement");
}

}  // namespace
}  // namespace lode::plugins
