// plant.maglev6: the paper's masses, inertias and stiffnesses (Silva-Rivas & Kim 2013), exact
// ZOH integration of the pure-mass and spring-mass axes, the surrogate input matrices (README),
// the disturbance wrench, the ProcessModel face, and the YAML path through io.sim.
#include "maglev6.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "plant_testing.hpp"

namespace lode::plugins {
namespace {

using plants::testing::configure_refused_naming;
using plants::testing::element_list;
using plants::testing::state_of;

constexpr double kDt = 1.0 / 800.0;  // the default rate (the paper gives none)

TEST(Maglev6, DeclaresPortsAndThePapersParameters) {
  Maglev6 plant;
  EXPECT_EQ(element_list(plant.inputs()), "iq_a [A], iq_b [A], iq_c [A], id_a [A], id_b [A], id_c [A]");
  const std::string pose = "x [m], y [m], theta_z [rad], z [m], theta_x [rad], theta_y [rad]";
  EXPECT_EQ(element_list(plant.outputs()), pose);
  EXPECT_EQ(element_list(plant.state_elements()),
            pose + ", vx [m/s], vy [m/s], omega_z [rad/s], vz [m/s], omega_x [rad/s], omega_y [rad/s]");
  // The estimator's f runs on the simulator's state and inputs.
  EXPECT_EQ(element_list(plant.process_state()), element_list(plant.state_elements()));
  EXPECT_EQ(element_list(plant.process_inputs()), element_list(plant.inputs()));
  EXPECT_EQ(plant.config().mass_kg, 1.52);
  EXPECT_EQ(plant.config().inertia_xx_kg_m2, 0.0037);
  EXPECT_EQ(plant.config().inertia_yy_kg_m2, 0.0019);
  EXPECT_EQ(plant.config().inertia_zz_kg_m2, 0.0022);
  EXPECT_EQ(plant.config().b_planar_acc_per_a(2, 2), -183.1);
  EXPECT_EQ(plant.config().b_vertical_acc_per_a(1, 2), 475.071);
}

TEST(Maglev6, VerticalNaturalFrequenciesFromThePapersStiffnesses) {
  // Derived from the paper's values: z 20.2 rad/s (3.21 Hz), theta 132.5 rad/s (21.1 Hz), psi 214 rad/s (34.1 Hz).
  Maglev6 plant;
  const auto& w = plant.natural_frequency_rad_s();
  EXPECT_EQ(w[Maglev6::kX], 0.0);
  EXPECT_EQ(w[Maglev6::kThetaZ], 0.0);
  EXPECT_NEAR(w[Maglev6::kZ], 20.2, 0.05);
  EXPECT_NEAR(w[Maglev6::kThetaX], 132.5, 0.05);
  EXPECT_NEAR(w[Maglev6::kThetaY], 214.0, 0.05);
  EXPECT_NEAR(w[Maglev6::kZ] / (2 * std::numbers::pi), 3.21, 0.005);
  EXPECT_NEAR(w[Maglev6::kThetaX] / (2 * std::numbers::pi), 21.1, 0.05);
  EXPECT_NEAR(w[Maglev6::kThetaY] / (2 * std::numbers::pi), 34.1, 0.05);
}

TEST(Maglev6, PlanarAxesIntegrateTheSurrogateBExactly) {
  // Constant currents: planar accelerations B_planar iq (the surrogate), closed-form parabola.
  Maglev6Config config;
  config.initial = {1e-3, -2e-3, 0.01, 0, 0, 0};
  config.initial_velocity = {0.02, -0.01, 0.1, 0, 0, 0};
  Maglev6 plant;
  plant.apply(config);
  const std::array<double, 6> u = {0.1, -0.05, 0.02, 0, 0, 0};
  const Eigen::Vector3d a = config.b_planar_acc_per_a * Eigen::Vector3d(u[0], u[1], u[2]);
  constexpr int kSteps = 8000;
  for (int k = 0; k < kSteps; ++k) plant.advance(kDt, u.data());
  const double t = kSteps * kDt;
  const auto x = state_of(plant);
  for (int i = 0; i < 3; ++i) {
    const auto axis = static_cast<std::size_t>(i);
    const double p = config.initial[axis] + config.initial_velocity[axis] * t + 0.5 * a(i) * t * t;
    const double v = config.initial_velocity[axis] + a(i) * t;
    EXPECT_NEAR(x[axis], p, 1e-12 * (std::abs(p) + 1.0)) << "axis " << i;
    EXPECT_NEAR(x[6 + axis], v, 1e-12 * (std::abs(v) + 1.0)) << "axis " << i;
  }
  // The vertical axes did not move (no direct current, no disturbance).
  for (std::size_t i = 3; i < 6; ++i) EXPECT_EQ(x[i], 0.0);
}

TEST(Maglev6, VerticalAxesAreUndampedSpringMassSystems) {
  // Free oscillation from an initial offset: z(t) = z0 cos(w t), exactly (eq. 3 with Kz).
  Maglev6Config config;
  config.initial = {0, 0, 0, 5e-6, 30e-6, -30e-6};
  Maglev6 plant;
  plant.apply(config);
  const std::array<double, 6> zero{};
  constexpr int kSteps = 8000;  // 10 s, 32 periods of z
  for (int k = 0; k < kSteps; ++k) plant.advance(kDt, zero.data());
  const auto x = state_of(plant);
  const auto& w = plant.natural_frequency_rad_s();
  const double t = kSteps * kDt;
  for (std::size_t i = 3; i < 6; ++i) {
    EXPECT_NEAR(x[i], config.initial[i] * std::cos(w[i] * t), 1e-12 * std::abs(config.initial[i])) << i;
    EXPECT_NEAR(x[6 + i], -config.initial[i] * w[i] * std::sin(w[i] * t), 1e-9 * std::abs(config.initial[i]) * w[i]);
  }
  // Constant direct currents: static deflection B_vertical id / (K / M) (spring equilibrium).
  plant.reset();
  Maglev6Config still;
  plant.apply(still);
  const std::array<double, 6> id = {0, 0, 0, 0.01, 0.01, 0.01};
  const Eigen::Vector3d a = still.b_vertical_acc_per_a * Eigen::Vector3d(0.01, 0.01, 0.01);
  // Integrate many periods and average: the mean of an undamped oscillation about the equilibrium.
  double mean[3] = {0, 0, 0};
  const int n = 80000;
  for (int k = 0; k < n; ++k) {
    plant.advance(kDt, id.data());
    double y[6];
    plant.output(y);
    for (int i = 0; i < 3; ++i) mean[i] += y[3 + i] / n;
  }
  for (int i = 0; i < 3; ++i) {
    const double omega = w[3 + static_cast<std::size_t>(i)];
    EXPECT_NEAR(mean[i], a(i) / (omega * omega), 2e-3 * std::abs(a(i) / (omega * omega))) << i;
  }
}

TEST(Maglev6, OneLongStepEqualsManyShortOnes) {
  Maglev6Config config;
  config.initial = {1e-4, 2e-4, 1e-3, 3e-6, 1e-5, -2e-5};
  config.initial_velocity = {1e-3, 0, 0, 1e-4, 1e-3, -1e-3};
  Maglev6 a, b;
  a.apply(config);
  b.apply(config);
  const std::array<double, 6> u = {0.3, -0.2, 0.1, 0.02, -0.01, 0.005};
  a.advance(0.01, u.data());
  for (int k = 0; k < 10; ++k) b.advance(0.001, u.data());
  const auto xa = state_of(a), xb = state_of(b);
  for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(xa[i], xb[i], 1e-13 * (std::abs(xa[i]) + 1e-3)) << i;
}

TEST(Maglev6, DisturbanceWrenchAcceleratesByForceOverInertia) {
  Maglev6Config config;
  config.disturbance_wrench = {0.152, 0, 2.2e-4, 0, 0, 0};  // 0.1 m/s^2 in x, 0.1 rad/s^2 about z
  Maglev6 plant;
  plant.apply(config);
  const std::array<double, 6> zero{};
  for (int k = 0; k < 800; ++k) plant.advance(kDt, zero.data());
  const auto x = state_of(plant);
  EXPECT_NEAR(x[6], 0.1, 1e-12);
  EXPECT_NEAR(x[8], 0.1, 1e-12);
  EXPECT_NEAR(x[0], 0.05, 1e-12);
}

TEST(Maglev6, ProcessModelSharesThePhysics) {
  Maglev6Config config;
  config.initial = {1e-4, 2e-4, 1e-3, 3e-6, 1e-5, -2e-5};
  config.initial_velocity = {1e-3, 0, 0, 1e-4, 1e-3, -1e-3};
  Maglev6 plant;
  plant.apply(config);
  const std::array<double, 6> u = {0.3, -0.2, 0.1, 0.02, -0.01, 0.005};
  auto x = state_of(plant);
  std::array<double, 12> next{};
  plant.propagate(kDt, x.data(), u.data(), next.data());
  plant.advance(kDt, u.data());
  EXPECT_EQ(next, state_of(plant));  // same code path, bit for bit

  // Analytic Jacobian against central differences.
  std::array<double, 144> f{};
  ASSERT_TRUE(plant.process_jacobian(kDt, x.data(), u.data(), f.data()));
  for (std::size_t j = 0; j < 12; ++j) {
    auto plus = x, minus = x;
    const double h = 1e-6;
    plus[j] += h;
    minus[j] -= h;
    std::array<double, 12> yp{}, ym{};
    plant.propagate(kDt, plus.data(), u.data(), yp.data());
    plant.propagate(kDt, minus.data(), u.data(), ym.data());
    for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(f[i * 12 + j], (yp[i] - ym[i]) / (2 * h), 1e-7) << i << "," << j;
  }
}

TEST(Maglev6, ModeMatricesAreTheEq11StateSpace) {
  Maglev6 plant;
  const Maglev6::Mode v = plant.vertical_mode();
  EXPECT_NEAR(v.a(3, 0), -620.0 / 1.52, 1e-9);
  EXPECT_NEAR(v.a(4, 1), -65.0 / 0.0037, 1e-6);
  EXPECT_NEAR(v.a(5, 2), -87.0 / 0.0019, 1e-6);
  EXPECT_EQ(v.a(0, 3), 1.0);
  EXPECT_EQ(v.b(4, 2), 475.071);
  const Maglev6::Mode h = plant.planar_mode();
  EXPECT_EQ(h.a.bottomRows<3>(), (Eigen::Matrix<double, 3, 6>::Zero()));
  EXPECT_EQ(h.b(3, 2), 12.903);
  EXPECT_EQ(h.c(2, 2), 1.0);
}

TEST(Maglev6, AdvanceAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Maglev6 plant;
  const std::array<double, 6> u = {0.3, -0.2, 0.1, 0.02, -0.01, 0.005};
  std::array<double, 12> x{}, next{}, f{};
  std::array<double, 144> jac{};
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) {
    plant.advance(kDt, u.data());
    plant.state(x.data());
    plant.propagate(kDt, x.data(), u.data(), next.data());
    plant.process_jacobian(kDt, x.data(), u.data(), jac.data());
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  (void)f;
}

// The YAML path: io.sim owns the plant in a pipeline; sensor.laser_gap reads z, theta_x, theta_y.
const char* kLaserModel = R"(
laser:
  plugin: sensor.laser_gap
  sensitivity_v_per_m: 1.0e4
  sensors:
    - {name: L1, x_m: 0.05, y_m: 0.0}
    - {name: L2, x_m: -0.025, y_m: 0.0433}
    - {name: L3, x_m: -0.025, y_m: -0.0433}
)";

TEST(Maglev6, ConfiguresThroughYamlAndReportsEveryProblem) {
  {
    const std::string models = std::string(kLaserModel) +
                               "stage:\n  plugin: plant.maglev6\n  mass_kg: 2.0\n  initial: [0, 0, 0, 1.0e-4, 0, 0]\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser\nnoise_std_v: 0\nadc_bits: 0", 800.0, models);
    h.feed("command", {{"iq_a", "A"}, {"iq_b", "A"}, {"iq_c", "A"}, {"id_a", "A"}, {"id_b", "A"}, {"id_c", "A"}});
    ASSERT_TRUE(h.configure()) << h.diagnostics();
    ASSERT_TRUE(h.activate());
    h.step();
    EXPECT_NEAR(h.output("truth")[3], 1e-4, 1e-15);
    EXPECT_NEAR(h.output("signals")[0], 1.0, 1e-12);  // 1e4 V/m * 100 um on every laser
    const Json j = h.describe();
    EXPECT_NE(j.dump().find("vertical_natural_frequency"), std::string::npos);
  }
  {
    const std::string models = std::string(kLaserModel) +
                               "stage:\n  plugin: plant.maglev6\n  mass_kg: -1\n  stiffness_z_n_per_m: -5\n"
                               "  b_planar_acc_per_a: [1, 2, 3, 2, 4, 6, 0, 0, 1]\n  initial: [0, 0]\n";
    lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: laser", 800.0, models);
    h.feed("command", {{"iq_a", "A"}, {"iq_b", "A"}, {"iq_c", "A"}, {"id_a", "A"}, {"id_b", "A"}, {"id_c", "A"}});
    EXPECT_TRUE(configure_refused_naming(h, {"mass_kg", "stiffness_z_n_per_m", "singular", "expected 6 numbers"}));
  }
}

}  // namespace
}  // namespace lode::plugins
