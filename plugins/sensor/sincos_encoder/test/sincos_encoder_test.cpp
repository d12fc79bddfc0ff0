// sensor.sincos_encoder: eq. 1/4 by hand, the corrected eq. 11 Jacobian against finite
// differences (and against the printed one, which it must not equal), periodicity and
// precision far from the origin, the optional offset/gain/phase terms, and the YAML path
// (hosted by estimator.ekf_encoder and io.sim, the blocks that use the model).
#include "sincos_encoder.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "lode/sdk/testing/harness.hpp"

namespace {

using lode::plugins::SincosEncoder;
using lode::plugins::SincosEncoderConfig;

constexpr double kPitch = 4e-6;  // Table 1
constexpr double kTwoPi = 2.0 * std::numbers::pi;

TEST(SincosEncoder, DeclaresOnePositionAndTwoVoltChannels) {
  SincosEncoder model;
  ASSERT_EQ(model.state_elements().size(), 1u);
  EXPECT_EQ(model.state_elements()[0].name, "x");
  EXPECT_EQ(model.state_elements()[0].unit, "m");
  ASSERT_EQ(model.channels().size(), 2u);
  EXPECT_EQ(model.channels()[0].name, "sin");
  EXPECT_EQ(model.channels()[1].name, "cos");
  EXPECT_EQ(model.channels()[0].unit, "V");
  EXPECT_EQ(model.channels()[1].unit, "V");
  // Table 1 by default.
  EXPECT_EQ(model.config().pitch_m, 4e-6);
  EXPECT_EQ(model.config().amplitude_v, 1.0);
  EXPECT_NEAR(model.wavenumber_rad_per_m(), kTwoPi * 2.5e5, 1e-9);  // 2 pi f_s, f_s = 2.5e5 1/m
}

TEST(SincosEncoder, IdealSignalsAreEquation4) {
  SincosEncoderConfig config;
  config.amplitude_v = 2.5;
  SincosEncoder model;
  ASSERT_TRUE(model.apply(config));
  for (double x : {0.0, 0.3e-6, 1.0e-6, 2.0e-6, 3.1e-6, -0.7e-6, 12.345e-6}) {
    double y[2];
    model.evaluate(&x, y);
    EXPECT_NEAR(y[0], 2.5 * std::sin(kTwoPi * 2.5e5 * x), 1e-12) << x;
    EXPECT_NEAR(y[1], 2.5 * std::cos(kTwoPi * 2.5e5 * x), 1e-12) << x;
  }
  // Quarter points exactly: 0, 1/4, 1/2 and 3/4 of a period.
  const std::array<std::array<double, 2>, 4> expected{{{0, 2.5}, {2.5, 0}, {0, -2.5}, {-2.5, 0}}};
  for (int q = 0; q < 4; ++q) {
    const double x = q * kPitch / 4;
    double y[2];
    model.evaluate(&x, y);
    EXPECT_NEAR(y[0], expected[q][0], 1e-14);
    EXPECT_NEAR(y[1], expected[q][1], 1e-14);
  }
}

TEST(SincosEncoder, PeriodicAndPreciseFarFromTheOrigin) {
  // 1 m of travel is 250000 periods: the phase must still be exact to well below the
  // paper's sub-nanometre errors (the argument is reduced in cycles before the sine).
  const SincosEncoder model;
  for (double base : {0.0, 1.0, -0.25}) {
    const double x = base + 0.125 * kPitch;  // 45 degrees
    double y[2];
    model.evaluate(&x, y);
    const double theta = std::atan2(y[0], y[1]);
    // A phase error d theta is a position error d theta / (2 pi f_s).
    EXPECT_NEAR(theta / model.wavenumber_rad_per_m(), 0.125 * kPitch, 1e-15) << "at " << base << " m";
    double y_next[2];
    const double x_next = x + kPitch;
    model.evaluate(&x_next, y_next);
    EXPECT_NEAR(y_next[0], y[0], 1e-9);
    EXPECT_NEAR(y_next[1], y[1], 1e-9);
  }
  EXPECT_NEAR(model.phase_rad(1.0 + kPitch / 4), std::numbers::pi / 2, 1e-9);
}

void expect_jacobian_matches_finite_differences(const SincosEncoder& model) {
  const double step = 1e-12;  // m; the signals vary on the 4 um scale
  for (int i = 0; i < 40; ++i) {
    const double x = -3e-6 + i * 0.237e-6;
    double y[2], H[2], y_plus[2], y_minus[2], y_only[2];
    model.jacobian(&x, y, H);
    model.evaluate(&x, y_only);
    EXPECT_EQ(y[0], y_only[0]);
    EXPECT_EQ(y[1], y_only[1]);
    const double xp = x + step, xm = x - step;
    model.evaluate(&xp, y_plus);
    model.evaluate(&xm, y_minus);
    for (int c = 0; c < 2; ++c) {
      const double numeric = (y_plus[c] - y_minus[c]) / (2 * step);
      // Central differences: truncation ~ w^3 step^2 ~ 4e6, rounding ~ 1e-16 / 1e-12 ~ 1e-4 V
      // per 1e-12 m, i.e. ~1e2 V/m against slopes of 1.6e6 V/m.
      EXPECT_NEAR(H[c], numeric, 1e-4 * model.wavenumber_rad_per_m()) << "x " << x << " channel " << c;
    }
  }
}

TEST(SincosEncoder, JacobianIsTheCorrectedEquation11) {
  const SincosEncoder model;
  expect_jacobian_matches_finite_differences(model);
  // dh/dx = 2 pi f_s V [cos(2 pi f_s x); -sin(2 pi f_s x)] at a quarter period: [0, -2 pi f_s V].
  const double x = kPitch / 4;
  double y[2], H[2];
  model.jacobian(&x, y, H);
  const double slope = model.wavenumber_rad_per_m();
  EXPECT_NEAR(H[0], 0.0, 1e-9 * slope);
  EXPECT_NEAR(H[1], -slope, 1e-9 * slope);
  // Eq. 11 as printed has cos(x) and -sin(x) of the bare position: at x = 1 um
  // that is ~[2 pi f_s V, 0], far from the true slope [0, -2 pi f_s V]; the model must not
  // be it.
  const double printed_sin_row = slope * std::cos(x);
  EXPECT_GT(std::abs(printed_sin_row - H[0]), 0.5 * slope);
}

TEST(SincosEncoder, OffsetGainAndQuadratureExtension) {
  SincosEncoderConfig config;
  config.amplitude_v = 1.2;
  config.offset_v = {0.010, -0.020};
  config.amplitude_ratio = 0.95;
  config.quadrature_error_rad = 0.03;
  config.channel_names = {"A", "B"};
  SincosEncoder model;
  ASSERT_TRUE(model.apply(config));
  EXPECT_EQ(model.channels()[0].name, "A");
  EXPECT_EQ(model.channels()[1].name, "B");
  for (double x : {0.0, 0.9e-6, 2.2e-6, -1.3e-6}) {
    const double theta = kTwoPi * x / kPitch;
    double y[2];
    model.evaluate(&x, y);
    EXPECT_NEAR(y[0], 1.2 * std::sin(theta) + 0.010, 1e-12);
    EXPECT_NEAR(y[1], 0.95 * 1.2 * std::cos(theta + 0.03) - 0.020, 1e-12);
  }
  expect_jacobian_matches_finite_differences(model);
}

TEST(SincosEncoder, RejectsInvalidDirectConfiguration) {
  SincosEncoder model;
  SincosEncoderConfig config;
  config.pitch_m = 0.0;
  EXPECT_FALSE(model.apply(config));
  config.pitch_m = 4e-6;
  config.amplitude_v = -1.0;
  EXPECT_FALSE(model.apply(config));
}

// --- YAML ------------------------------------------------------------------------------------

TEST(SincosEncoderYaml, ConfiguresFromYamlLikeTheDirectConfig) {
  // io.sim with no noise and no converter publishes exactly h(truth).
  lode::testing::BlockHarness h("io.sim", "plant: axis\nsensors: [head]\nnoise_std_v: 0\nadc_bits: 0\n", 20000.0,
                                "axis: {plugin: plant.encoder_stage, offset_m: 1.0e-6}\n"
                                "head: {plugin: sensor.sincos_encoder, pitch_m: 4.0e-6, amplitude_v: 2.0,\n"
                                "       channels: [a, b], offset_v: [0.1, -0.1]}\n");
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  const auto& names = h.output_elements("signals");
  ASSERT_EQ(names.size(), 2u);
  EXPECT_EQ(names[0].name, "a");
  EXPECT_EQ(names[1].name, "b");
  // x = 1 um = a quarter period: sin = 2 V, cos = 0 V, plus the offsets.
  EXPECT_NEAR(h.output("signals")[0], 2.1, 1e-12);
  EXPECT_NEAR(h.output("signals")[1], -0.1, 1e-12);
}

TEST(SincosEncoderYaml, LocatedErrorsForEveryBadKey) {
  lode::testing::BlockHarness h("estimator.ekf_encoder", "model: head", 20000.0,
                                "head: {plugin: sensor.sincos_encoder, pitch_m: -4.0e-6, amplitude_v: 0,\n"
                                "       channels: [a], amplitude_ratio: -1, quadrature_error_rad: 2.0}\n");
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  for (const char* key : {"pitch_m", "amplitude_v", "channels", "amplitude_ratio", "quadrature_error_rad"}) {
    EXPECT_NE(d.find(std::string("head.") + key), std::string::npos) << key << " not reported in:\n" << d;
  }
}

TEST(SincosEncoderYaml, PitchIsRequired) {
  lode::testing::BlockHarness h("estimator.ekf_encoder", "model: head", 20000.0,
                                "head: {plugin: sensor.sincos_encoder}\n");
  h.feed("signals", {{"sin", "V"}, {"cos", "V"}});
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("pitch_m"), std::string::npos) << h.diagnostics();
}

}  // namespace
