// plant.planar_stage: exact zero-order-hold integration, work-energy balance, the yaw
// coupling and disturbance terms, reset, and the YAML path (through io.sim, the block that
// owns a plant in a pipeline).
#include "planar_stage.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <regex>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/require.hpp"

namespace {

using lode::plugins::PlanarStage;
using lode::plugins::PlanarStageConfig;

constexpr double kDt = 1.0 / 800.0;  // the thesis's 800 Hz loop

std::array<double, PlanarStage::kStateSize> state_of(const PlanarStage& stage) {
  std::array<double, PlanarStage::kStateSize> x{};
  stage.state(x.data());
  return x;
}

TEST(PlanarStage, DeclaresPortsWithSiUnits) {
  PlanarStage stage;
  const lode::Elements& u = stage.inputs();
  ASSERT_EQ(u.size(), 3u);
  EXPECT_EQ(u[0].name, "fx");
  EXPECT_EQ(u[0].unit, "N");
  EXPECT_EQ(u[1].name, "fy");
  EXPECT_EQ(u[1].unit, "N");
  EXPECT_EQ(u[2].name, "tz");
  EXPECT_EQ(u[2].unit, "N*m");
  const lode::Elements& y = stage.outputs();
  ASSERT_EQ(y.size(), 3u);
  EXPECT_EQ(y[2].name, "theta_z");
  EXPECT_EQ(y[2].unit, "rad");
  const lode::Elements& s = stage.state_elements();
  ASSERT_EQ(s.size(), 6u);
  EXPECT_EQ(s[3].name, "vx");
  EXPECT_EQ(s[3].unit, "m/s");
  EXPECT_EQ(s[5].name, "omega_z");
  EXPECT_EQ(s[5].unit, "rad/s");
  // Thesis values by default (eq. 4.44-4.47).
  EXPECT_EQ(stage.config().mass_kg, 6.20);
  EXPECT_EQ(stage.config().inertia_kg_m2, 0.054);
}

// Constant inputs over many cycles: the ZOH integration must equal the closed form
// p(t) = p0 + v0 t + a t^2 / 2, v(t) = v0 + a t with no integration error at all.
TEST(PlanarStage, ZohMatchesClosedFormForConstantForce) {
  PlanarStageConfig config;
  config.initial = {1e-3, -2e-3, 0.01};
  config.initial_velocity = {0.02, -0.01, 0.5};
  PlanarStage stage;
  stage.apply(config);
  const std::array<double, 3> u = {3.1, -1.7, 0.025};
  constexpr int kSteps = 8000;  // 10 s
  for (int k = 0; k < kSteps; ++k) stage.advance(kDt, u.data());

  const double t = kSteps * kDt;
  const std::array<double, 3> a = {u[0] / 6.20, u[1] / 6.20, u[2] / 0.054};
  const auto x = state_of(stage);
  for (int axis = 0; axis < 3; ++axis) {
    const double p = config.initial[axis] + config.initial_velocity[axis] * t + 0.5 * a[axis] * t * t;
    const double v = config.initial_velocity[axis] + a[axis] * t;
    // Only rounding accumulates over 8000 steps: relative 1e-12 is far above it.
    EXPECT_NEAR(x[axis], p, 1e-12 * (std::abs(p) + 1.0)) << "axis " << axis;
    EXPECT_NEAR(x[3 + axis], v, 1e-12 * (std::abs(v) + 1.0)) << "axis " << axis;
  }
  double y[3];
  stage.output(y);
  EXPECT_EQ(y[0], x[0]);
  EXPECT_EQ(y[1], x[1]);
  EXPECT_EQ(y[2], x[2]);
}

// Exactness also means one long step equals many short ones with the same held input.
TEST(PlanarStage, IntegrationIsIndependentOfStepSize) {
  PlanarStage coarse;
  PlanarStage fine;
  PlanarStageConfig config;
  config.initial_velocity = {0.1, 0.2, -0.3};
  coarse.apply(config);
  fine.apply(config);
  const std::array<double, 3> u = {-2.0, 5.0, 0.1};
  coarse.advance(0.5, u.data());
  for (int k = 0; k < 400; ++k) fine.advance(0.5 / 400.0, u.data());
  const auto xc = state_of(coarse);
  const auto xf = state_of(fine);
  for (std::size_t i = 0; i < xc.size(); ++i) EXPECT_NEAR(xc[i], xf[i], 1e-13) << "state " << i;
}

// With piecewise-constant forces the work done in each step, F . (p_{k+1} - p_k), equals the
// change of kinetic energy exactly (it is the exact solution); summed over random forces the
// balance must hold to rounding.
TEST(PlanarStage, WorkEqualsKineticEnergyChange) {
  PlanarStageConfig config;
  config.initial_velocity = {0.01, -0.02, 0.05};
  PlanarStage stage;
  stage.apply(config);
  auto kinetic = [&](const std::array<double, 6>& x) {
    return 0.5 * config.mass_kg * (x[3] * x[3] + x[4] * x[4]) +
           0.5 * config.inertia_kg_m2 * x[5] * x[5];
  };
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> force(-10.0, 10.0);
  std::uniform_real_distribution<double> torque(-0.2, 0.2);
  const double energy0 = kinetic(state_of(stage));
  double work = 0.0;
  for (int k = 0; k < 4000; ++k) {
    const std::array<double, 3> u = {force(rng), force(rng), torque(rng)};
    const auto before = state_of(stage);
    stage.advance(kDt, u.data());
    const auto after = state_of(stage);
    work += u[0] * (after[0] - before[0]) + u[1] * (after[1] - before[1]) +
            u[2] * (after[2] - before[2]);
  }
  const double energy1 = kinetic(state_of(stage));
  EXPECT_NEAR(work, energy1 - energy0, 1e-9 * (std::abs(energy1) + std::abs(energy0)));
  EXPECT_GT(std::abs(energy1 - energy0), 1e-3);  // the forces did real work
}

// The thesis's force asymmetry: fx applied with a lever arm also turns the platen,
// tz_eff = tz + lever * fx; x is unaffected by the lever.
TEST(PlanarStage, YawCouplingTurnsXForceIntoMoment) {
  PlanarStageConfig config;
  config.yaw_coupling_m = 0.05;
  PlanarStage stage;
  stage.apply(config);
  const std::array<double, 3> u = {2.0, 0.0, 0.0};
  for (int k = 0; k < 800; ++k) stage.advance(kDt, u.data());
  const double t = 800 * kDt;
  const auto x = state_of(stage);
  const double alpha = 0.05 * 2.0 / 0.054;
  EXPECT_NEAR(x[PlanarStage::kThetaZ], 0.5 * alpha * t * t, 1e-12);
  EXPECT_NEAR(x[PlanarStage::kOmegaZ], alpha * t, 1e-12);
  EXPECT_NEAR(x[PlanarStage::kX], 0.5 * (2.0 / 6.20) * t * t, 1e-12);
  EXPECT_EQ(x[PlanarStage::kY], 0.0);

  // fy has no lever: no yaw.
  stage.reset();
  const std::array<double, 3> uy = {0.0, 2.0, 0.0};
  for (int k = 0; k < 800; ++k) stage.advance(kDt, uy.data());
  EXPECT_EQ(state_of(stage)[PlanarStage::kThetaZ], 0.0);

  // The lever and a commanded torque add: tz = -lever * fx cancels the yaw exactly.
  stage.reset();
  const std::array<double, 3> cancel = {2.0, 0.0, -0.05 * 2.0};
  for (int k = 0; k < 800; ++k) stage.advance(kDt, cancel.data());
  EXPECT_NEAR(state_of(stage)[PlanarStage::kThetaZ], 0.0, 1e-15);
}

TEST(PlanarStage, DisturbanceTorqueAcceleratesYawAtRest) {
  PlanarStageConfig config;
  config.disturbance_torque_n_m = -0.002;  // a cable pulling the platen round
  PlanarStage stage;
  stage.apply(config);
  const std::array<double, 3> zero = {0.0, 0.0, 0.0};
  for (int k = 0; k < 1600; ++k) stage.advance(kDt, zero.data());
  const double t = 1600 * kDt;
  EXPECT_NEAR(state_of(stage)[PlanarStage::kThetaZ], 0.5 * (-0.002 / 0.054) * t * t, 1e-13);
  EXPECT_EQ(state_of(stage)[PlanarStage::kX], 0.0);
}

TEST(PlanarStage, ResetRestoresInitialCondition) {
  PlanarStageConfig config;
  config.initial = {0.01, 0.02, -0.03};
  config.initial_velocity = {0.1, 0.0, 0.2};
  PlanarStage stage;
  stage.apply(config);
  const std::array<double, 3> u = {1.0, 1.0, 1.0};
  for (int k = 0; k < 100; ++k) stage.advance(kDt, u.data());
  EXPECT_NE(state_of(stage)[0], 0.01);
  stage.reset();
  const auto x = state_of(stage);
  EXPECT_EQ(x[0], 0.01);
  EXPECT_EQ(x[1], 0.02);
  EXPECT_EQ(x[2], -0.03);
  EXPECT_EQ(x[3], 0.1);
  EXPECT_EQ(x[4], 0.0);
  EXPECT_EQ(x[5], 0.2);
}

// ---- The YAML path: parameters reach the physics, invalid ones are located errors. -----
// In a pipeline only io.sim owns a plant, and io.sim needs a measurement model: these tests
// use sensor.halbach_hall and are skipped (with the reason) when it is not built.


const char* const kHallModel =
    "hall: {plugin: sensor.halbach_hall, sensors: [{name: A, x_m: 0.00635, y_m: 0.09525}, "
    "{name: B, x_m: -0.00635, y_m: -0.09525}]}\n";

TEST(PlanarStageYaml, ParametersReachThePhysics) {
  LODE_REQUIRE_PLUGINS("sensor.halbach_hall");
  lode::testing::BlockHarness h(
      "io.sim", "plant: stage\nsensors: hall\nnoise_std_v: 0\n", 800.0,
      std::string("stage: {plugin: plant.planar_stage, mass_kg: 2.0, inertia_kg_m2: 0.1, "
                  "initial: [0.001, 0.002, 0.003], initial_velocity: [0, 0, 0], "
                  "yaw_coupling_m: 0.01, disturbance_torque_n_m: 0.001}\n") +
          kHallModel);
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto command = h.input("command");
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_EQ(h.output("truth")[0], 0.001);
  EXPECT_EQ(h.output("truth")[1], 0.002);
  EXPECT_EQ(h.output("truth")[2], 0.003);
  command[0] = 4.0;
  command[1] = -1.0;
  command[2] = 0.05;
  ASSERT_EQ(h.write(), lode::StepStatus::ok);
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  const double half_dt2 = 0.5 * kDt * kDt;
  EXPECT_NEAR(h.output("truth")[0] - 0.001, 4.0 / 2.0 * half_dt2, 1e-18);
  EXPECT_NEAR(h.output("truth")[1] - 0.002, -1.0 / 2.0 * half_dt2, 1e-18);
  EXPECT_NEAR(h.output("truth")[2] - 0.003, (0.05 + 0.01 * 4.0 + 0.001) / 0.1 * half_dt2, 1e-18);
  EXPECT_NEAR(h.output("plant_state")[3], 4.0 / 2.0 * kDt, 1e-15);
}

TEST(PlanarStageYaml, NonPositiveMassAndInertiaAreLocatedErrors) {
  LODE_REQUIRE_PLUGINS("sensor.halbach_hall");
  lode::testing::BlockHarness h(
      "io.sim", "plant: stage\nsensors: hall\n", 800.0,
      std::string("stage: {plugin: plant.planar_stage, mass_kg: -6.2, inertia_kg_m2: 0}\n") +
          kHallModel);
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("models.stage.mass_kg: must be > 0 kg, got -6.2"), std::string::npos) << d;
  EXPECT_NE(d.find("models.stage.inertia_kg_m2: must be > 0"), std::string::npos) << d;
  EXPECT_TRUE(std::regex_search(d, std::regex(R"(<block_host:io\.sim>:\d+:\d+: models\.stage\.mass_kg)")))
      << "errors carry file:line:column: " << d;
  EXPECT_EQ(d.find("has no input"), std::string::npos) << "no follow-on errors: " << d;
}

TEST(PlanarStageYaml, WrongInitialSizeIsRejected) {
  LODE_REQUIRE_PLUGINS("sensor.halbach_hall");
  lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: hall\n", 800.0,
                                std::string("stage: {plugin: plant.planar_stage, initial: [1, 2]}\n") +
                                    kHallModel);
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("models.stage.initial: expected 3 numbers, got 2"),
            std::string::npos)
      << h.diagnostics();
}

}  // namespace
