// plant.encoder_stage: the paper's test inputs (Tables 2-4) sampled exactly, time
// kept without drift over long fast runs, reset, and the YAML path (hosted by io.sim).
#include "encoder_stage.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "plant_testing.hpp"

namespace {

using lode::plugins::EncoderStage;
using lode::plugins::EncoderStageConfig;
using lode::plugins::plants::testing::configure_refused_naming;
using lode::plugins::plants::testing::element_list;
using lode::plugins::plants::testing::state_of;

constexpr double kDt = 1.0 / 20000.0;  // Table 1: 20 kHz
constexpr double kTwoPi = 2.0 * std::numbers::pi;

TEST(EncoderStage, HasNoInputsAndOutputsPositionAndVelocity) {
  const EncoderStage stage;
  EXPECT_TRUE(stage.inputs().empty());
  EXPECT_EQ(element_list(stage.outputs()), "x [m], v [m/s]");
  EXPECT_EQ(element_list(stage.state_elements()), "x [m], v [m/s], a [m/s^2]");
}

TEST(EncoderStage, SinusoidIsSampledExactly) {
  // x = A sin(2 pi f t): the paper's 5 Hz, 1 um input, and its analytic derivatives.
  EncoderStageConfig config;
  config.amplitude_m = 1e-6;
  config.frequency_hz = 5.0;
  EncoderStage stage;
  stage.apply(config);
  const double w = kTwoPi * 5.0;
  for (int k = 0; k < 40000; ++k) {  // 2 s
    const double t = k * kDt;
    const auto x = state_of(stage);
    ASSERT_NEAR(x[EncoderStage::kX], 1e-6 * std::sin(w * t), 1e-17) << "k " << k;
    ASSERT_NEAR(x[EncoderStage::kV], 1e-6 * w * std::cos(w * t), 1e-15) << "k " << k;
    ASSERT_NEAR(x[EncoderStage::kA], -1e-6 * w * w * std::sin(w * t), 1e-13) << "k " << k;
    stage.advance(kDt, nullptr);
  }
}

TEST(EncoderStage, RampOffsetAndPhase) {
  EncoderStageConfig config;
  config.offset_m = 3e-6;
  config.velocity_m_s = 2e-3;  // the paper's constant-velocity input
  config.amplitude_m = 0.5e-6;
  config.frequency_hz = 2.0;
  config.phase_rad = 0.4;
  EncoderStage stage;
  stage.apply(config);
  for (int k = 0; k < 2000; ++k) stage.advance(kDt, nullptr);
  const double t = 2000 * kDt;
  const double w = kTwoPi * 2.0;
  double y[2];
  stage.output(y);
  EXPECT_NEAR(y[0], 3e-6 + 2e-3 * t + 0.5e-6 * std::sin(w * t + 0.4), 1e-17);
  EXPECT_NEAR(y[1], 2e-3 + 0.5e-6 * w * std::cos(w * t + 0.4), 1e-15);
}

TEST(EncoderStage, VelocityIsTheDerivativeOfPosition) {
  EncoderStageConfig config;
  config.amplitude_m = 2e-6;
  config.frequency_hz = 10.0;
  config.velocity_m_s = -1e-3;
  EncoderStage stage;
  stage.apply(config);
  for (double t : {0.0, 0.013, 0.07, 0.51}) {
    const double h = 1e-7;
    const auto plus = stage.trajectory(t + h);
    const auto minus = stage.trajectory(t - h);
    const auto here = stage.trajectory(t);
    EXPECT_NEAR(here[1], (plus[0] - minus[0]) / (2 * h), 1e-9);
    EXPECT_NEAR(here[2], (plus[1] - minus[1]) / (2 * h), 1e-6);
  }
}

TEST(EncoderStage, TimeDoesNotDriftOverLongFastRuns) {
  // 1e6 steps of 10 us (the 100 kHz case of Table 4 for 10 s): plain summation of a
  // non-representable step drifts by ~1e-9 s; the compensated sum stays at rounding.
  EncoderStage stage;
  for (int k = 0; k < 1000000; ++k) stage.advance(1e-5, nullptr);
  EXPECT_NEAR(stage.time_s(), 10.0, 1e-13);
}

TEST(EncoderStage, ResetRestoresTheStart) {
  EncoderStageConfig config;
  config.amplitude_m = 1e-6;
  config.frequency_hz = 5.0;
  config.phase_rad = 1.0;
  EncoderStage stage;
  stage.apply(config);
  const auto start = state_of(stage);
  for (int k = 0; k < 123; ++k) stage.advance(kDt, nullptr);
  EXPECT_NE(state_of(stage)[0], start[0]);
  stage.reset();
  EXPECT_EQ(state_of(stage), start);
  EXPECT_EQ(stage.time_s(), 0.0);
}

// --- YAML, through io.sim (the block that owns a plant in a pipeline) --------------------------

const char* kModels =
    "axis: {plugin: plant.encoder_stage, amplitude_m: 1.0e-6, frequency_hz: 5.0, velocity_m_s: 1.0e-3,\n"
    "       offset_m: 2.0e-6, phase_rad: 0.25}\n"
    "head: {plugin: sensor.sincos_encoder, pitch_m: 4.0e-6}\n";

TEST(EncoderStageYaml, IoSimPublishesTheTrajectoryAtEverySample) {
  lode::testing::BlockHarness h("io.sim", "plant: axis\nsensors: head\nnoise_std_v: 0\nadc_bits: 0\n", 20000.0,
                                kModels);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const double w = kTwoPi * 5.0;
  for (int k = 0; k < 500; ++k) {
    ASSERT_EQ(h.step(), lode::StepStatus::ok);
    const double t = k * kDt;
    // Sample k shows the stage at t_k = k T: the read phase comes before the advance.
    EXPECT_NEAR(h.output("truth")[0], 2e-6 + 1e-3 * t + 1e-6 * std::sin(w * t + 0.25), 1e-17) << k;
    EXPECT_NEAR(h.output("truth")[1], 1e-3 + 1e-6 * w * std::cos(w * t + 0.25), 1e-15) << k;
    EXPECT_NEAR(h.output("plant_state")[2], -1e-6 * w * w * std::sin(w * t + 0.25), 1e-13) << k;
    const double x = h.output("truth")[0];
    EXPECT_NEAR(h.output("signals")[0], std::sin(kTwoPi * x / 4e-6), 1e-9) << k;
    ASSERT_EQ(h.write(), lode::StepStatus::ok);
  }
}

TEST(EncoderStageYaml, InvalidValuesAreLocatedErrors) {
  lode::testing::BlockHarness h("io.sim", "plant: axis\nsensors: head\n", 20000.0,
                                "axis: {plugin: plant.encoder_stage, amplitude_m: -1.0e-6, frequency_hz: -5}\n"
                                "head: {plugin: sensor.sincos_encoder, pitch_m: 4.0e-6}\n");
  h.feed("command", {{"unused", "1"}});
  EXPECT_TRUE(configure_refused_naming(h, {"axis.amplitude_m", "axis.frequency_hz"}));
}

}  // namespace
