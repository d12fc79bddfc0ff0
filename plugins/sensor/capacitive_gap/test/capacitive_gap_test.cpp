// sensor.capacitive_gap: home reads 0 V at 1 mm, translations along a probe axis open its gap
// one for one, tilts act through the lever arms, the analytic Jacobian matches central
// differences at a large pose, the exact flat-target geometry (cosine effect) and the YAML path.
#include "capacitive_gap.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/require.hpp"
#include "plant_testing.hpp"

namespace {

using lode::plugins::CapacitiveGap;
using lode::plugins::CapacitiveGapConfig;
using lode::plugins::plants::testing::configure_refused_naming;

std::vector<double> gaps_at(const CapacitiveGap& model, const std::array<double, 6>& pose) {
  std::vector<double> g(model.channels().size());
  model.gaps(pose.data(), g.data());
  return g;
}

TEST(CapacitiveGap, DefaultLayoutReadsZeroVoltsAtHome) {
  CapacitiveGap model;
  ASSERT_EQ(model.channels().size(), 6u);
  EXPECT_EQ(model.channels()[0].name, "z1");
  EXPECT_EQ(model.channels()[0].unit, "V");
  ASSERT_EQ(model.state_elements().size(), 6u);
  EXPECT_EQ(model.state_elements()[4].name, "theta");
  EXPECT_EQ(model.state_elements()[4].unit, "rad");
  const std::array<double, 6> home{};
  std::vector<double> y(6);
  model.evaluate(home.data(), y.data());
  for (double v : y) EXPECT_EQ(v, 0.0);
  for (double g : gaps_at(model, home)) EXPECT_NEAR(g, 1e-3, 1e-18);
}

TEST(CapacitiveGap, TranslationAlongAProbeAxisOpensItsGap) {
  CapacitiveGap model;
  const std::vector<double> g = gaps_at(model, {1e-6, -2e-6, 3e-6, 0, 0, 0});
  // z1..z3 see +3 um, x1 and x2 +1 um, y1 -2 um (their axes are +z, +x, +y).
  EXPECT_NEAR(g[0] - 1e-3, 3e-6, 1e-18);
  EXPECT_NEAR(g[2] - 1e-3, 3e-6, 1e-18);
  EXPECT_NEAR(g[3] - 1e-3, 1e-6, 1e-18);
  EXPECT_NEAR(g[5] - 1e-3, -2e-6, 1e-18);
  std::vector<double> y(6);
  const std::array<double, 6> pose{1e-6, 0, 0, 0, 0, 0};
  model.evaluate(pose.data(), y.data());
  EXPECT_NEAR(y[3], 2e4 * 1e-6, 1e-12);  // 20 mV per um
}

// A small pitch theta about y lowers the +x side: z1 at x = +50 mm sees -0.05 theta; the yaw psi
// moves x1 (y = +40 mm) by -0.04 psi and x2 by +0.04 psi.
TEST(CapacitiveGap, TiltsActThroughTheLeverArms) {
  CapacitiveGap model;
  const double a = 4e-6;  // the paper's 4 urad; second-order terms (lever * a^2 ~ 1e-13 m) are below 1e-12
  const std::vector<double> pitch = gaps_at(model, {0, 0, 0, 0, a, 0});
  EXPECT_NEAR(pitch[0] - 1e-3, -0.05 * a, 1e-12);
  EXPECT_NEAR(pitch[1] - 1e-3, 0.025 * a, 1e-12);
  const std::vector<double> yaw = gaps_at(model, {0, 0, 0, 0, 0, a});
  EXPECT_NEAR(yaw[3] - 1e-3, -0.04 * a, 1e-12);
  EXPECT_NEAR(yaw[4] - 1e-3, 0.04 * a, 1e-12);
  const std::vector<double> roll = gaps_at(model, {0, 0, 0, a, 0, 0});
  EXPECT_NEAR(roll[1] - 1e-3, std::sqrt(3.0) / 2.0 * 0.05 * a, 1e-12);
}

// Exact flat-target geometry: a probe looking along +z at a target point (0, L, 0) sees, under a
// roll phi about x, the plane through (0, L cos phi, L sin phi) with normal (0, -sin phi, cos phi);
// its axis meets that plane at g = g0 + L tan(phi) (not the small-angle g0 + L phi). A target point
// on the axis gives g0 for any tilt, and a flat target sliding across the axis leaves g unchanged.
TEST(CapacitiveGap, ExactFlatTargetGeometry) {
  const double lever = 0.05;
  CapacitiveGapConfig c;
  c.probes = {{"off_axis", Eigen::Vector3d(0, lever, 0), Eigen::Vector3d::UnitZ()},
              {"on_axis", Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitZ()}};
  CapacitiveGap model;
  model.apply(c);
  const double phi = 0.2;
  const std::vector<double> tilted = gaps_at(model, {0, 0, 0, phi, 0, 0});
  EXPECT_NEAR(tilted[0], 1e-3 + lever * std::tan(phi), 1e-17);
  EXPECT_NEAR(tilted[1], 1e-3, 1e-18);
  const std::vector<double> slid = gaps_at(model, {2e-3, -1e-3, 0, 0, 0, 0});
  EXPECT_NEAR(slid[0], 1e-3, 1e-18);
  EXPECT_NEAR(slid[1], 1e-3, 1e-18);
}

TEST(CapacitiveGap, AnalyticJacobianMatchesCentralDifferences) {
  CapacitiveGap model;
  const std::array<double, 6> pose{2e-4, -3e-4, 1e-4, 0.02, -0.03, 0.05};  // far beyond the experiments
  std::vector<double> y(6), h(36);
  model.jacobian(pose.data(), y.data(), h.data());
  std::vector<double> y_eval(6);
  model.evaluate(pose.data(), y_eval.data());
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(y[i], y_eval[i]);
  for (std::size_t j = 0; j < 6; ++j) {
    const double step = j < 3 ? 1e-7 : 1e-6;
    std::array<double, 6> plus = pose, minus = pose;
    plus[j] += step;
    minus[j] -= step;
    std::vector<double> yp(6), ym(6);
    model.evaluate(plus.data(), yp.data());
    model.evaluate(minus.data(), ym.data());
    for (std::size_t i = 0; i < 6; ++i) {
      const double numeric = (yp[i] - ym[i]) / (2.0 * step);
      EXPECT_NEAR(h[i * 6 + j], numeric, 1e-6 * (std::abs(numeric) + 1.0)) << "channel " << i << " state " << j;
    }
  }
}


TEST(CapacitiveGapYaml, ProbesAndScaleReachTheModel) {
  LODE_REQUIRE_PLUGINS("plant.rigid_body6");
  lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: gaps\nnoise_std_v: 0\nadc_bits: 0\n", 2500.0,
                                "stage: {plugin: plant.rigid_body6, initial: [1e-6, 0, 2e-6, 0, 0, 0]}\n"
                                "gaps:\n"
                                "  plugin: sensor.capacitive_gap\n"
                                "  sensitivity_v_per_m: 1e4\n"
                                "  zero_gap_m: 0.5e-3\n"
                                "  probes:\n"
                                "    - {name: a, target_m: [0, 0, 0], axis: [0, 0, 2]}\n"
                                "    - {name: b, target_m: [0, 0, 0], axis: [1, 0, 0]}\n");
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  ASSERT_EQ(h.output_elements("signals").size(), 2u);
  EXPECT_EQ(h.output_elements("signals")[1].name, "b");
  h.step();
  EXPECT_NEAR(h.output("signals")[0], 1e4 * (1e-3 + 2e-6 - 0.5e-3), 1e-12);  // axis normalised
  EXPECT_NEAR(h.output("signals")[1], 1e4 * (1e-3 + 1e-6 - 0.5e-3), 1e-12);
}

TEST(CapacitiveGapYaml, BadProbesAreLocatedErrors) {
  LODE_REQUIRE_PLUGINS("plant.rigid_body6");
  lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: gaps\n", 2500.0,
                                "stage: {plugin: plant.rigid_body6}\n"
                                "gaps:\n"
                                "  plugin: sensor.capacitive_gap\n"
                                "  sensitivity_v_per_m: 0\n"
                                "  probes:\n"
                                "    - {name: a, target_m: [0, 0, 0], axis: [0, 0, 0]}\n"
                                "    - {name: a, target_m: [0, 0], axis: [1, 0, 0]}\n");
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}});
  EXPECT_TRUE(configure_refused_naming(h, {"sensitivity_v_per_m", "non-zero vector", "duplicate probe name", "target_m"}));
}

}  // namespace
