// Tests of sensor.halbach_hall: the Fourier physics against an independent amplitude table, the
// channel model and its analytic Jacobian, the least-squares property of the [1, 5] model and
// the located configuration errors.
#include "halbach_hall.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins {
namespace {

constexpr double kPitch = 0.0508;
constexpr double kPi = std::numbers::pi;

/// The thesis geometry, assumed (the thesis shows it only in Fig. 28): A = (+6.35, +95.25) mm,
/// B = (-6.35, -95.25) mm.
HalbachHallConfig two_sensor_config(std::vector<int> harmonics = {1, 5}) {
  HalbachHallConfig c;
  c.harmonics = std::move(harmonics);
  HalbachSensorConfig a;
  a.name = "A";
  a.x_m = 0.00635;
  a.y_m = 0.09525;
  a.channels = {"a1", "b1"};
  HalbachSensorConfig b;
  b.name = "B";
  b.x_m = -0.00635;
  b.y_m = -0.09525;
  b.channels = {"c1", "d2"};
  c.sensors = {a, b};
  return c;
}

double default_ratio() { return std::numbers::sqrt2 * 1.10 / 1.43; }

// ---------------------------------------------------------------------------------------
// Physics (eq. 3.5-3.14; README "Deviations" 1-2)

TEST(HalbachPhysics, FundamentalAmplitudeAt2mmMatchesAnIndependentTable) {
  // Independent table, Z0 = 2 mm: 0.416 T with r = 1.088 (sqrt(2) B_r,weak / B_r,strong), 0.352 T with the
  // printed ratio 0.769. The table has three digits: tolerance half a unit of the last digit.
  const auto actual = halbach_field_harmonic(1, kPitch, 0.002, 0.0127, 1.43, default_ratio());
  const auto printed = halbach_field_harmonic(1, kPitch, 0.002, 0.0127, 1.43, 1.10 / 1.43);
  EXPECT_NEAR(default_ratio(), 1.088, 0.0005);
  EXPECT_NEAR(actual.amplitude_t(), 0.416, 0.0005);
  EXPECT_NEAR(printed.amplitude_t(), 0.352, 0.0005);
}

TEST(HalbachPhysics, AmplitudeTableAtAllGaps) {
  struct Row {
    double gap_m, n1_r0769, n1_r1088, n3_r0769, n3_r1088, n5_r0769, n5_r1088, n5_over_n1;
  };
  // Independent table, strong side up, M0 = B_r,strong / (2 mu0), Delta = 12.7 mm.
  const Row rows[] = {{0.001, 0.399, 0.470, 0.017, 0.006, 0.061, 0.072, 0.154},
                      {0.002, 0.352, 0.416, 0.012, 0.004, 0.033, 0.039, 0.094},
                      {0.003, 0.311, 0.367, 0.008, 0.003, 0.018, 0.021, 0.057},
                      {0.005, 0.243, 0.287, 0.004, 0.002, 0.005, 0.006, 0.021}};
  for (const Row& row : rows) {
    SCOPED_TRACE("gap " + std::to_string(row.gap_m));
    auto h = [&](int n, double r) {
      return halbach_field_harmonic(n, kPitch, row.gap_m, 0.0127, 1.43, r).amplitude_t();
    };
    // The table has three decimals: half a unit of the last digit.
    const double tol = 0.0005 + 1e-9;
    EXPECT_NEAR(h(1, 1.10 / 1.43), row.n1_r0769, tol);
    EXPECT_NEAR(h(1, default_ratio()), row.n1_r1088, tol);
    EXPECT_NEAR(h(3, 1.10 / 1.43), row.n3_r0769, tol);
    // One cell of the table is rounded twice: 0.00146 T -> 0.0015 -> "0.002" at 5 mm.
    EXPECT_NEAR(h(3, default_ratio()), row.n3_r1088, row.gap_m == 0.005 ? 0.0006 : tol);
    EXPECT_NEAR(h(5, 1.10 / 1.43), row.n5_r0769, tol);
    EXPECT_NEAR(h(5, default_ratio()), row.n5_r1088, tol);
    // n5/n1 does not depend on r: both scale with (1 + r).
    EXPECT_NEAR(h(5, default_ratio()) / h(1, default_ratio()), row.n5_over_n1, tol);
    EXPECT_NEAR(h(5, 1.10 / 1.43) / h(1, 1.10 / 1.43), row.n5_over_n1, tol);
  }
}

TEST(HalbachPhysics, StrongSideShapeAndSigns) {
  // Strong side: B_X(X) ~ -A1 sin(kX) + A5 sin(5kX) - A9 sin(9kX); no cosine terms; the 5th and
  // the fundamental share zero crossings; beta/alpha ~ -0.094 at 2 mm.
  const double r = default_ratio();
  const auto h1 = halbach_field_harmonic(1, kPitch, 0.002, 0.0127, 1.43, r);
  const auto h5 = halbach_field_harmonic(5, kPitch, 0.002, 0.0127, 1.43, r);
  const auto h9 = halbach_field_harmonic(9, kPitch, 0.002, 0.0127, 1.43, r);
  EXPECT_LT(h1.sin_t, 0.0);
  EXPECT_GT(h5.sin_t, 0.0);
  EXPECT_LT(h9.sin_t, 0.0);
  for (const auto& h : {h1, h5, h9}) EXPECT_NEAR(h.cos_t, 0.0, 1e-15);
  EXPECT_NEAR(h5.sin_t / h1.sin_t, -0.094, 0.0005);
  // Ideal array (r = 1): the 3rd and 7th cancel exactly (README "Deviations" 2).
  EXPECT_NEAR(halbach_field_harmonic(3, kPitch, 0.002, 0.0127, 1.43, 1.0).amplitude_t(), 0.0, 1e-15);
  EXPECT_NEAR(halbach_field_harmonic(7, kPitch, 0.002, 0.0127, 1.43, 1.0).amplitude_t(), 0.0, 1e-15);
}

TEST(HalbachPhysics, ModelCoefficientsAreSensitivityTimesField) {
  HalbachHall model;
  ASSERT_TRUE(model.apply(two_sensor_config({1, 3, 5, 7, 9})).is_ok());
  EXPECT_NEAR(model.effective_weak_ratio(), default_ratio(), 1e-15);
  for (std::size_t h = 0; h < model.harmonics().size(); ++h) {
    const auto field = halbach_field_harmonic(model.harmonics()[h], kPitch, 0.002, 0.0127, 1.43,
                                              default_ratio());
    for (std::size_t ch = 0; ch < 4; ++ch) {
      EXPECT_DOUBLE_EQ(model.sin_coefficient_v(ch, h), 8.43 * field.sin_t);
      EXPECT_DOUBLE_EQ(model.cos_coefficient_v(ch, h), 8.43 * field.cos_t);
    }
  }
  // alpha at 2 mm ~ 8.43 V/T x 0.416 T = 3.5 V (an estimate of 3.0-3.5 V; the thesis prints no fit).
  EXPECT_NEAR(std::abs(model.sin_coefficient_v(0, 0)), 3.507, 0.005);
}

TEST(HalbachPhysics, WeakRatioOverride) {
  HalbachHallConfig c = two_sensor_config();
  c.weak_ratio = 1.10 / 1.43;
  HalbachHall model;
  ASSERT_TRUE(model.apply(c).is_ok());
  EXPECT_NEAR(std::abs(model.sin_coefficient_v(1, 0)), 8.43 * 0.352, 8.43 * 0.0005);
}

// ---------------------------------------------------------------------------------------
// Channel model (eq. 4.19-4.26)

TEST(HalbachModel, ChannelNamesAndOrder) {
  HalbachHallConfig c = two_sensor_config();
  c.sensors[1].channels.clear();
  HalbachHall model;
  ASSERT_TRUE(model.apply(c).is_ok());
  ASSERT_EQ(model.channels().size(), 4u);
  EXPECT_EQ(model.channels()[0].name, "a1");
  EXPECT_EQ(model.channels()[1].name, "b1");
  EXPECT_EQ(model.channels()[2].name, "B_a");
  EXPECT_EQ(model.channels()[3].name, "B_b");
  for (const auto& e : model.channels()) EXPECT_EQ(e.unit, "V");
  ASSERT_EQ(model.state_elements().size(), 3u);
  EXPECT_EQ(model.state_elements()[0].name, "x");
  EXPECT_EQ(model.state_elements()[2].name, "theta_z");
  EXPECT_EQ(model.state_elements()[2].unit, "rad");
}

TEST(HalbachModel, CurveFitChannelsMatchHandComputation) {
  // Explicit coefficients with offsets, phases and a rotation, against eq. 4.19-4.26 written out.
  HalbachHallConfig c = two_sensor_config();
  c.sensors[0].offset_v = {0.05, -0.03};
  c.sensors[0].x_phase_m = 0.001;
  c.sensors[0].y_phase_m = -0.002;
  c.coefficients = {{0.10, 3.0, -0.28}, {-0.20, 3.2, -0.30}, {0.01, 2.9, -0.27}, {0.02, 3.1, -0.29}};
  HalbachHall model;
  ASSERT_TRUE(model.apply(c).is_ok());

  const double state[3] = {0.0123, -0.0071, 0.03};
  double y[4];
  model.evaluate(state, y);

  const double w = 2.0 * kPi / kPitch;
  const double th = state[2];
  struct S {
    double xs, ys, ca, cb, xph, yph;
    HalbachCurveFit fa, fb;
  };
  const S sensors[2] = {{0.00635, 0.09525, 0.05 + 0.10, -0.03 - 0.20, 0.001, -0.002,
                         c.coefficients[0], c.coefficients[1]},
                        {-0.00635, -0.09525, 0.01, 0.02, 0.0, 0.0, c.coefficients[2],
                         c.coefficients[3]}};
  for (int i = 0; i < 2; ++i) {
    const S& s = sensors[i];
    const double xw = state[0] + s.xs * std::cos(th) - s.ys * std::sin(th);
    const double yw = state[1] + s.xs * std::sin(th) + s.ys * std::cos(th);
    const double A = s.fa.alpha_v * std::sin(w * (yw - s.yph)) + s.fa.beta_v * std::sin(5 * w * (yw - s.yph));
    const double B = s.fb.alpha_v * std::sin(w * (xw - s.xph)) + s.fb.beta_v * std::sin(5 * w * (xw - s.xph));
    EXPECT_NEAR(y[2 * i], s.ca + A * std::cos(th) + B * std::sin(th), 1e-12);
    EXPECT_NEAR(y[2 * i + 1], s.cb - A * std::sin(th) + B * std::cos(th), 1e-12);
  }
}

TEST(HalbachModel, RotationOnlyTurnsTheFieldPart) {
  // |(a - c_a, b - c_b)| is the in-plane field magnitude: invariant under theta for a sensor at
  // the centre of mass (whose world position does not move with theta).
  HalbachHallConfig c = two_sensor_config();
  c.sensors[0].x_m = 0.0;
  c.sensors[0].y_m = 0.0;
  c.sensors[0].offset_v = {0.3, -0.4};
  HalbachHall model;
  ASSERT_TRUE(model.apply(c).is_ok());
  double y0[4];
  const double s0[3] = {0.004, 0.011, 0.0};
  model.evaluate(s0, y0);
  const double m0 = std::hypot(y0[0] - 0.3, y0[1] + 0.4);
  for (double th : {-0.1, -0.01, 0.02, 0.15}) {
    double y[4];
    const double s[3] = {0.004, 0.011, th};
    model.evaluate(s, y);
    EXPECT_NEAR(std::hypot(y[0] - 0.3, y[1] + 0.4), m0, 1e-12);
    // eq. 4.23: a = c + A cos th + B sin th with A, B the theta = 0 field parts.
    EXPECT_NEAR(y[0] - 0.3, (y0[0] - 0.3) * std::cos(th) + (y0[1] + 0.4) * std::sin(th), 1e-12);
  }
}

// ---------------------------------------------------------------------------------------
// Analytic Jacobian vs finite differences (brief test 1)

/// Fourth-order central difference (Richardson): truncation ~ h^4 f^(5)/30, negligible here.
void finite_difference_jacobian(const HalbachHall& model, const double* state, double* H) {
  const std::size_t m = model.channels().size();
  std::vector<double> yp(m), ym(m), yp2(m), ym2(m);
  for (int k = 0; k < 3; ++k) {
    const double h = 1e-5;  // m or rad (the 95 mm lever makes 1e-5 rad ~ 1 um)
    double s[3] = {state[0], state[1], state[2]};
    s[k] = state[k] + h;
    model.evaluate(s, yp.data());
    s[k] = state[k] - h;
    model.evaluate(s, ym.data());
    s[k] = state[k] + 2 * h;
    model.evaluate(s, yp2.data());
    s[k] = state[k] - 2 * h;
    model.evaluate(s, ym2.data());
    for (std::size_t i = 0; i < m; ++i)
      H[i * 3 + k] = (8.0 * (yp[i] - ym[i]) - (yp2[i] - ym2[i])) / (12.0 * h);
  }
}

/// Worst relative error over `poses` random poses; relative to max(|H_ij|, column scale) so
/// entries that vanish (e.g. da/dx = B' sin(theta)) are judged on the column's magnitude.
double worst_jacobian_error(const HalbachHall& model, int poses, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pos(-kPitch, kPitch);
  std::uniform_real_distribution<double> rot(-0.1, 0.1);
  const std::size_t m = model.channels().size();
  std::vector<double> y(m), H(m * 3), F(m * 3), y_eval(m);
  double worst = 0.0;
  for (int p = 0; p < poses; ++p) {
    const double state[3] = {pos(rng), pos(rng), rot(rng)};
    model.jacobian(state, y.data(), H.data());
    model.evaluate(state, y_eval.data());
    for (std::size_t i = 0; i < m; ++i) EXPECT_EQ(y[i], y_eval[i]);
    finite_difference_jacobian(model, state, F.data());
    for (int k = 0; k < 3; ++k) {
      double column_scale = 0.0;
      for (std::size_t i = 0; i < m; ++i) column_scale = std::max(column_scale, std::abs(H[i * 3 + k]));
      for (std::size_t i = 0; i < m; ++i) {
        const double denom = std::max(std::abs(H[i * 3 + k]), column_scale);
        worst = std::max(worst, std::abs(H[i * 3 + k] - F[i * 3 + k]) / denom);
      }
    }
  }
  return worst;
}

TEST(HalbachJacobian, MatchesFiniteDifferencesHarmonics15) {
  HalbachHall model;
  ASSERT_TRUE(model.apply(two_sensor_config({1, 5})).is_ok());
  const double worst = worst_jacobian_error(model, 250, 1);
  RecordProperty("worst_relative_error", std::to_string(worst));
  std::printf("[1,5]: worst relative Jacobian error over 250 poses = %.3g\n", worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(HalbachJacobian, MatchesFiniteDifferencesHarmonics13579) {
  HalbachHall model;
  ASSERT_TRUE(model.apply(two_sensor_config({1, 3, 5, 7, 9})).is_ok());
  const double worst = worst_jacobian_error(model, 250, 2);
  std::printf("[1,3,5,7,9]: worst relative Jacobian error over 250 poses = %.3g\n", worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(HalbachJacobian, MatchesFiniteDifferencesCurveFitWithPhasesAndThreeSensors) {
  HalbachHallConfig c = two_sensor_config();
  HalbachSensorConfig s;
  s.name = "C";
  s.x_m = 0.0;
  s.y_m = 0.0;
  s.x_phase_m = 0.003;
  s.y_phase_m = -0.004;
  s.offset_v = {0.06, -0.02};
  c.sensors.push_back(s);
  c.coefficients = {{0.1, 3.0, -0.28}, {-0.2, 3.2, -0.3}, {0.01, 2.9, -0.27},
                    {0.02, 3.1, -0.29}, {0.0, -3.3, 0.31}, {0.0, 2.8, 0.25}};
  HalbachHall model;
  ASSERT_TRUE(model.apply(c).is_ok());
  const double worst = worst_jacobian_error(model, 200, 3);
  std::printf("curve fit, 3 sensors: worst relative Jacobian error over 200 poses = %.3g\n", worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(HalbachJacobian, WouldCatchTheThesisListingBug) {
  // The printed listing has "- b10*Ct" instead of "- b10*St" in db/dtheta (README "Deviations" 4).
  // Show that the finite-difference check has the power to see an error of that size.
  HalbachHall model;
  ASSERT_TRUE(model.apply(two_sensor_config()).is_ok());
  const double state[3] = {0.01, 0.02, 0.05};
  double y[4], H[12], F[12];
  model.jacobian(state, y, H);
  finite_difference_jacobian(model, state, F);
  // Field parts at this pose (offsets are 0): A = a cos + ..., recover B from the rotation.
  const double th = state[2];
  const double B = y[0] * std::sin(th) + y[1] * std::cos(th);
  const double buggy = H[1 * 3 + 2] + B * std::sin(th) - B * std::cos(th);
  EXPECT_GT(std::abs(buggy - F[1 * 3 + 2]) / std::abs(F[1 * 3 + 2]), 1e-3);
  EXPECT_LT(std::abs(H[1 * 3 + 2] - F[1 * 3 + 2]) / std::abs(F[1 * 3 + 2]), 1e-6);
}

// ---------------------------------------------------------------------------------------
// The [1, 5] physics model is the least-squares fit of the richer field (thesis eq. 4.11)

TEST(HalbachLeastSquares, BatchFitOfRicherFieldEqualsHarmonics15Model) {
  // The simulator's "true" field has harmonics [1,3,5,7,9]; fit c + alpha sin(wu) + beta sin(5wu)
  // by batch least squares (eq. 4.11, x = (H'H)^-1 H'y) to samples over one pitch at theta = 0.
  // Sines and cosines of different harmonics are orthogonal over a full period (also for
  // N equally spaced samples when N > 2*9), so the fit returns exactly the [1,5] coefficients.
  HalbachHallConfig rich_config = two_sensor_config({1, 3, 5, 7, 9});
  rich_config.sensors[0].offset_v = {0.07, -0.05};
  HalbachHallConfig fit_config = two_sensor_config({1, 5});
  fit_config.sensors[0].offset_v = {0.07, -0.05};
  HalbachHall rich;
  HalbachHall fit;
  ASSERT_TRUE(rich.apply(rich_config).is_ok());
  ASSERT_TRUE(fit.apply(fit_config).is_ok());

  constexpr int kSamples = 64;
  const double w = 2.0 * kPi / kPitch;
  const double xa = 0.00635;  // sensor A body x: channel b1 sees X = x + xa at theta = 0
  Eigen::MatrixXd H(kSamples, 3);
  Eigen::VectorXd y(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    const double x = kPitch * k / kSamples - 0.3 * kPitch;
    const double state[3] = {x, 0.0, 0.0};
    double channels[4];
    rich.evaluate(state, channels);
    const double u = x + xa;
    H.row(k) << 1.0, std::sin(w * u), std::sin(5 * w * u);
    y(k) = channels[1];
  }
  const Eigen::Vector3d estimate = (H.transpose() * H).ldlt().solve(H.transpose() * y);
  std::printf("batch LS fit of the [1..9] field: c = %.12f V, alpha = %.12f V, beta = %.12f V\n",
              estimate(0), estimate(1), estimate(2));
  std::printf("[1,5] physics model:            c = %.12f V, alpha = %.12f V, beta = %.12f V\n",
              fit.dc_v(1), fit.sin_coefficient_v(1, 0), fit.sin_coefficient_v(1, 1));
  EXPECT_NEAR(estimate(0), fit.dc_v(1), 1e-12);
  EXPECT_NEAR(estimate(1), fit.sin_coefficient_v(1, 0), 1e-12);
  EXPECT_NEAR(estimate(2), fit.sin_coefficient_v(1, 1), 1e-12);

  // What the fit leaves over is what the [1,5] model cannot represent: on a fine grid, the
  // largest |truth - fit| is the model error that describe() reports.
  double worst_residual = 0.0;
  for (int k = 0; k < 4096; ++k) {
    const double x = kPitch * k / 4096.0 - xa;
    const double state[3] = {x, 0.0, 0.0};
    double channels[4];
    rich.evaluate(state, channels);
    const double u = x + xa;
    const double fitted = estimate(0) + estimate(1) * std::sin(w * u) + estimate(2) * std::sin(5 * w * u);
    worst_residual = std::max(worst_residual, std::abs(channels[1] - fitted));
  }
  EXPECT_NEAR(worst_residual, rich.max_model_error_v(), 1e-9);
  EXPECT_GT(rich.max_model_error_v(), 0.0);
  EXPECT_EQ(fit.max_model_error_v(), 0.0);
  std::printf("max |[1..9] - [1,5]| over a pitch = %.4f V\n", rich.max_model_error_v());
}

TEST(HalbachLeastSquares, MaxModelErrorMatchesIndependentSampling) {
  HalbachHall rich;
  ASSERT_TRUE(rich.apply(two_sensor_config({1, 3, 5, 7, 9})).is_ok());
  const double r = default_ratio();
  double worst = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const double u = kPitch * k / 20000.0;
    double e = 0.0;
    for (int n : {3, 7, 9}) {
      const auto h = halbach_field_harmonic(n, kPitch, 0.002, 0.0127, 1.43, r);
      e += 8.43 * h.sin_t * std::sin(n * 2 * kPi * u / kPitch);
    }
    worst = std::max(worst, std::abs(e));
  }
  EXPECT_NEAR(rich.max_model_error_v(), worst, 1e-4);
}

// ---------------------------------------------------------------------------------------
// Validation

std::string problems_of(const HalbachHallConfig& c) {
  HalbachHall model;
  const Status s = model.apply(c);
  return s.is_ok() ? std::string() : s.message();
}

TEST(HalbachValidation, RejectsBadConfigurationsNamingTheKey) {
  {
    HalbachHallConfig c = two_sensor_config({1, 4, 5});
    EXPECT_NE(problems_of(c).find("harmonics"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config({1, 5, 5});
    EXPECT_NE(problems_of(c).find("listed twice"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config({1, 3, 5});
    c.coefficients.assign(4, HalbachCurveFit{0.0, 3.0, -0.3});
    EXPECT_NE(problems_of(c).find("imply harmonics [1, 5]"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config();
    c.coefficients.assign(3, HalbachCurveFit{0.0, 3.0, -0.3});
    EXPECT_NE(problems_of(c).find("coefficients: needs one entry per channel"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config();
    c.sensors[1].channels = {"a1", "x"};
    EXPECT_NE(problems_of(c).find("sensors[1].channels: channel name 'a1' is used twice"),
              std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config();
    c.sensors[1].name = "A";
    EXPECT_NE(problems_of(c).find("sensors[1].name"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config();
    c.sensors.clear();
    EXPECT_NE(problems_of(c).find("sensors: needs 1 to 8 sensors"), std::string::npos);
  }
  {
    HalbachHallConfig c = two_sensor_config();
    c.gap_m = -0.001;
    c.pitch_m = 0.0;
    c.sensitivity_v_per_t = 0.0;
    const std::string p = problems_of(c);
    EXPECT_NE(p.find("gap_m"), std::string::npos);
    EXPECT_NE(p.find("pitch_m"), std::string::npos);
    EXPECT_NE(p.find("sensitivity_v_per_t"), std::string::npos);
  }
  EXPECT_EQ(problems_of(two_sensor_config()), "");
}

// Through YAML: the estimator block asks the pipeline for the model, which reports problems at
// their file:line:column. (estimator.glsdc is a plugin of this project, built before the tests.)
constexpr const char* kGoodModels = R"(
hall:
  plugin: sensor.halbach_hall
  gap_m: 0.002
  harmonics: [1, 3, 5, 7, 9]
  sensors:
    - {name: A, x_m: 0.00635, y_m: 0.09525, channels: [a1, b1], offset_v: [0.05, -0.03]}
    - {name: B, x_m: -0.00635, y_m: -0.09525, channels: [c1, d2], x_phase_m: 0.001}
)";

TEST(HalbachYaml, ConfiguresFromYamlLikeTheDirectConfig) {
  lode::testing::BlockHarness h("estimator.glsdc", "model: hall", 800.0, kGoodModels);
  h.feed("measurement", {{"a1", "V"}, {"b1", "V"}, {"c1", "V"}, {"d2", "V"}});
  ASSERT_TRUE(h.configure().is_ok()) << h.diagnostics();
  const Json d = h.describe();
  const Json* model = d.find("model_description");
  ASSERT_NE(model, nullptr) << d.dump();
  HalbachHallConfig c = two_sensor_config({1, 3, 5, 7, 9});
  c.sensors[0].offset_v = {0.05, -0.03};
  c.sensors[1].x_phase_m = 0.001;
  HalbachHall direct;
  ASSERT_TRUE(direct.apply(c).is_ok());
  Json expected = Json::object();
  direct.describe(expected);
  EXPECT_EQ(model->dump(), expected.dump());
}

TEST(HalbachYaml, LocatedErrors) {
  const std::string models = R"(
hall:
  plugin: sensor.halbach_hall
  harmonics: [1, 2, 5]
  sensors:
    - {name: A, x_m: 0.00635, y_m: 0.09525, channels: [a1, b1]}
    - {name: B, x_m: -0.00635, channels: [a1, d2, e3]}
)";
  lode::testing::BlockHarness h("estimator.glsdc", "model: hall", 800.0, models);
  EXPECT_FALSE(h.configure().is_ok());
  const std::string d = h.diagnostics();
  std::printf("%s\n", d.c_str());
  EXPECT_NE(d.find("models.hall.harmonics"), std::string::npos) << d;
  EXPECT_NE(d.find("models.hall.sensors[1].y_m"), std::string::npos) << d;
  EXPECT_NE(d.find("models.hall.sensors[1].channels"), std::string::npos) << d;
}

TEST(HalbachYaml, LocatedErrorsForCurveFit) {
  const std::string models = R"(
hall:
  plugin: sensor.halbach_hall
  gap_m: 0.003
  sensors:
    - {name: A, x_m: 0.00635, y_m: 0.09525}
    - {name: B, x_m: -0.00635, y_m: -0.09525}
  coefficients:
    - {c_v: 0.1, alpha_v: 3.0, beta_v: -0.3}
    - {c_v: 0.1, alpha_v: 3.0}
    - {c_v: 0.1, alpha_v: 3.0, beta_v: -0.3}
    - {c_v: 0.1, alpha_v: 3.0, beta_v: -0.3, zeta_v: 0.0}
)";
  lode::testing::BlockHarness h("estimator.glsdc", "model: hall", 800.0, models);
  EXPECT_FALSE(h.configure().is_ok());
  const std::string d = h.diagnostics();
  std::printf("%s\n", d.c_str());
  EXPECT_NE(d.find("models.hall.gap_m"), std::string::npos) << d;
  EXPECT_NE(d.find("models.hall.coefficients[1].beta_v"), std::string::npos) << d;
}

TEST(HalbachYaml, UnknownKeysInsideListEntriesAreReported) {
  // A typo inside a `sensors` entry must not pass silently (the core's unread-key check).
  const std::string models = R"(
hall:
  plugin: sensor.halbach_hall
  sensors:
    - {name: A, x_m: 0.00635, y_m: 0.09525, ofset_v: [0.1, 0.1]}
    - {name: B, x_m: -0.00635, y_m: -0.09525}
)";
  lode::testing::BlockHarness h("estimator.glsdc", "model: hall", 800.0, models);
  h.feed("measurement", {{"A_a", "V"}, {"A_b", "V"}, {"B_a", "V"}, {"B_b", "V"}});
  EXPECT_FALSE(h.configure().is_ok());
  EXPECT_NE(h.diagnostics().find("models.hall.sensors[0].ofset_v"), std::string::npos)
      << h.diagnostics();
}

}  // namespace
}  // namespace lode::plugins
