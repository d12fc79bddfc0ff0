// sensor.laser_gap: the rigid-body displacement of each spot, the analytic Jacobian, the
// pose-noise figure of describe(), and configuration checks (through io.sim with
// plant.maglev6, the way a pipeline loads the model).
#include "laser_gap.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins {
namespace {

std::vector<LaserSpot> triangle() {
  // Three spots on a 50 mm circle, 120 degrees apart (the pipeline's assumption).
  return {{"L1", 0.05, 0.0, 1.0}, {"L2", -0.025, 0.0433, -0.5}, {"L3", -0.025, -0.0433, 0.0}};
}

TEST(LaserGap, MeasuresTheDisplacementOfEachSpot) {
  LaserGap laser;
  laser.apply(triangle(), 2.0e4);
  ASSERT_EQ(laser.channels().size(), 3u);
  EXPECT_EQ(laser.channels()[1].name, "L2");
  EXPECT_EQ(laser.channels()[1].unit, "V");
  ASSERT_EQ(laser.state_elements().size(), 3u);
  EXPECT_EQ(laser.state_elements()[1].name, "theta_x");
  // Pure lift: every spot rises by z.
  const double lift[3] = {5e-6, 0.0, 0.0};
  double y[3];
  laser.evaluate(lift, y);
  EXPECT_NEAR(y[0], 1.0 + 2e4 * 5e-6, 1e-12);
  EXPECT_NEAR(y[1], -0.5 + 2e4 * 5e-6, 1e-12);
  // Tilt about x raises the +y spot, about y lowers the +x spot (right-hand rule).
  const double tilt_x[3] = {0.0, 30e-6, 0.0};
  laser.evaluate(tilt_x, y);
  EXPECT_NEAR(y[1] + 0.5, 2e4 * 0.0433 * std::sin(30e-6), 1e-12);
  EXPECT_NEAR(y[2], -2e4 * 0.0433 * std::sin(30e-6), 1e-12);
  const double tilt_y[3] = {0.0, 0.0, 30e-6};
  laser.evaluate(tilt_y, y);
  EXPECT_NEAR(y[0] - 1.0, -2e4 * 0.05 * std::sin(30e-6), 1e-12);
  // Combined, against the rotation matrix R = Rx(tx) Ry(ty) applied to the spot.
  const double pose[3] = {1e-4, 0.02, -0.03};
  laser.evaluate(pose, y);
  for (std::size_t i = 0; i < 3; ++i) {
    const LaserSpot s = triangle()[i];
    const double tx = pose[1], ty = pose[2];
    // Ry: (x, y, 0) -> (x cos ty, y, -x sin ty); Rx: z' = y sin tx + z cos tx.
    const double z_body = s.y_m * std::sin(tx) + (-s.x_m * std::sin(ty)) * std::cos(tx);
    EXPECT_NEAR(y[i], s.offset_v + 2e4 * (pose[0] + z_body), 1e-12) << i;
  }
}

TEST(LaserGap, JacobianMatchesCentralDifferences) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  LaserGap laser;
  laser.apply(triangle(), -1.5e4);
  const std::array<double, 3> x = {2e-5, 0.01, -0.02};
  std::array<double, 3> y{}, y0{};
  std::array<double, 9> h{};
  laser.jacobian(x.data(), y.data(), h.data());
  laser.evaluate(x.data(), y0.data());
  EXPECT_EQ(y, y0);
  for (std::size_t j = 0; j < 3; ++j) {
    auto plus = x, minus = x;
    plus[j] += 1e-7;
    minus[j] -= 1e-7;
    std::array<double, 3> yp{}, ym{};
    laser.evaluate(plus.data(), yp.data());
    laser.evaluate(minus.data(), ym.data());
    for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(h[3 * i + j], (yp[i] - ym[i]) / 2e-7, 1e-4) << i << j;
  }
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 1000; ++k) laser.jacobian(x.data(), y.data(), h.data());
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

TEST(LaserGap, PoseNoisePerVoltFollowsTheGeometry) {
  // Three spots at 120 degrees on radius a: (H'H) = diag(3, 3a^2/2, 3a^2/2) s^2, so the
  // least-squares z noise is sigma / (s sqrt(3)) and the tilt noise sigma sqrt(2/3) / (s a).
  LaserGap laser;
  const double a = 0.05;
  laser.apply({{"L1", a, 0.0, 0.0},
               {"L2", a * std::cos(2.0944), a * std::sin(2.0944), 0.0},
               {"L3", a * std::cos(4.18879), a * std::sin(4.18879), 0.0}},
              1e4);
  const std::vector<double> n = laser.pose_noise_per_volt();
  EXPECT_NEAR(n[0], 1.0 / (1e4 * std::sqrt(3.0)), 1e-9);
  EXPECT_NEAR(n[1], std::sqrt(2.0 / 3.0) / (1e4 * a), 1e-7);
  EXPECT_NEAR(n[2], std::sqrt(2.0 / 3.0) / (1e4 * a), 1e-7);
}

const Elements kCommand = {{"iq_a", "A"}, {"iq_b", "A"}, {"iq_c", "A"}, {"id_a", "A"}, {"id_b", "A"}, {"id_c", "A"}};

TEST(LaserGap, LoadsFromYamlAndRejectsBadGeometry) {
  {
    const std::string models =
        "stage: {plugin: plant.maglev6, initial: [0, 0, 0, 2.0e-6, 0, 0]}\n"
        "laser:\n  plugin: sensor.laser_gap\n  sensitivity_v_per_m: 1.0e4\n  sensors:\n"
        "    - {name: L1, x_m: 0.05, y_m: 0.0, offset_v: 0.5}\n"
        "    - {name: L2, x_m: -0.025, y_m: 0.0433}\n"
        "    - {name: L3, x_m: -0.025, y_m: -0.0433}\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser\nnoise_std_v: 0\nadc_bits: 0", 800.0, models);
    h.feed("command", kCommand);
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    ASSERT_TRUE(h.activate());
    h.step();
    EXPECT_NEAR(h.output("signals")[0], 0.5 + 0.02, 1e-12);
    EXPECT_NEAR(h.output("signals")[2], 0.02, 1e-12);
    EXPECT_EQ(h.output_elements("signals")[1].name, "L2");
  }
  {
    const std::string models =
        "stage: {plugin: plant.maglev6}\n"
        "laser:\n  plugin: sensor.laser_gap\n  sensitivity_v_per_m: 0\n  sensors:\n"
        "    - {name: L1, x_m: 0.0, y_m: 0.0}\n"
        "    - {name: L1, x_m: 0.01, y_m: 0.01}\n"
        "    - {name: L3, x_m: 0.02, y_m: 0.02}\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser", 800.0, models);
    h.feed("command", kCommand);
    EXPECT_FALSE(h.configure());
    const std::string d = h.diagnostics();
    EXPECT_NE(d.find("sensitivity_v_per_m"), std::string::npos) << d;
    EXPECT_NE(d.find("duplicate sensor name"), std::string::npos) << d;
  }
  {
    const std::string models =
        "stage: {plugin: plant.maglev6}\n"
        "laser:\n  plugin: sensor.laser_gap\n  sensitivity_v_per_m: 1.0e4\n  sensors:\n"
        "    - {name: L1, x_m: 0.0, y_m: 0.0}\n"
        "    - {name: L2, x_m: 0.01, y_m: 0.01}\n"
        "    - {name: L3, x_m: 0.02, y_m: 0.02}\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser", 800.0, models);
    h.feed("command", kCommand);
    EXPECT_FALSE(h.configure());
    EXPECT_NE(h.diagnostics().find("one line"), std::string::npos) << h.diagnostics();
  }
  {
    const std::string models =
        "stage: {plugin: plant.maglev6}\n"
        "laser:\n  plugin: sensor.laser_gap\n  sensitivity_v_per_m: 1.0e4\n  sensors:\n"
        "    - {name: L1, x_m: 0.0, y_m: 0.0}\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser", 800.0, models);
    h.feed("command", kCommand);
    EXPECT_FALSE(h.configure());
    EXPECT_NE(h.diagnostics().find("needs 3 to 8"), std::string::npos) << h.diagnostics();
  }
}

}  // namespace
}  // namespace lode::plugins
