// Tests of estimator.glsdc through the BlockHarness (the scheduler's port API), with the real
// sensor.halbach_hall model from `models:` both as the estimator's h(z) and as the "truth"
// that makes the measurements (thesis geometry, with positions assumed since the thesis shows
// them only in Fig. 28: A = (+6.35, +95.25) mm, B = (-6.35, -95.25) mm, 2 mm gap).
#include "glsdc.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "estimator/testing/harness_setup.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"
#include "glsdc_rig.hpp"


namespace lode::plugins {
namespace {

using namespace glsdc_testing;

// ---------------------------------------------------------------------------------------

TEST(Glsdc, DeclaresPortsAndDescribes) {
  Rig rig("model: hall\nnoise_std_v: [1e-3, 2e-3, 1e-3, 1e-3]", hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  const Elements& pose = rig.harness().output_elements("pose");
  ASSERT_EQ(pose.size(), 3u);
  EXPECT_EQ(pose[0].name, "x");
  EXPECT_EQ(pose[2].unit, "rad");
  const Elements& cov = rig.harness().output_elements("covariance");
  ASSERT_EQ(cov.size(), 9u);
  EXPECT_EQ(cov[0].name, "xx");
  EXPECT_EQ(cov[2].unit, "m*rad");
  EXPECT_EQ(cov[8].name, "thth");
  EXPECT_EQ(cov[8].unit, "rad^2");
  EXPECT_EQ(rig.harness().output_elements("cost")[0].unit, "1");
  const Json d = rig.harness().describe();
  ASSERT_NE(d.find("weight_diagonal_1_per_v2"), nullptr) << d.dump();
  const auto& w = d.find("weight_diagonal_1_per_v2")->elements();
  ASSERT_EQ(w.size(), 4u);
  EXPECT_NEAR(w[0].as_number(), 1e6, 1e-3);
  EXPECT_NEAR(w[1].as_number(), 0.25e6, 1e-3);
  EXPECT_EQ(d.find("mode")->as_string(), "3dof");
  EXPECT_EQ(d.find("model")->as_string(), "hall");
  EXPECT_EQ(d.find("iterations")->as_number(), 1.0);
  EXPECT_EQ(d.find("backoff")->as_number(), 0.2);
}

TEST(Glsdc, ConfigurationErrorsAreLocated) {
  const std::string models = hall_model("hall", "[1, 5]");
  struct Case {
    std::string params;
    std::string expect;
  };
  const Case cases[] = {
      {"model: hall\nmode: 6dof", "dut.mode"},
      {"model: hall\niterations: 0", "dut.iterations"},
      {"model: hall\nbackoff: 1.5", "dut.backoff"},
      {"model: hall\nnoise_std_v: [1e-3, 1e-3]", "dut.noise_std_v"},
      {"model: hall\nnoise_std_v: -1e-3", "dut.noise_std_v"},
      {"model: hall\ninitial: [0, 0]", "dut.initial"},
      {"model: nosuch", "dut.model"},
      {"model: hall\nbakoff: 0.3", "dut.bakoff"},
  };
  for (const Case& c : cases) {
    BlockHarness h("estimator.glsdc", c.params, kRateHz, models);
    h.feed("measurement", channel_elements(false));
    EXPECT_FALSE(h.configure().is_ok()) << c.params;
    EXPECT_NE(h.diagnostics().find(c.expect), std::string::npos)
        << c.params << "\n" << h.diagnostics();
  }
}

TEST(Glsdc, ActivateResetsToInitial) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  Rig rig(params_with_initial(0.001, -0.002, 0.003), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  EXPECT_EQ(rig.pose(0), 0.001);
  EXPECT_EQ(rig.pose(1), -0.002);
  EXPECT_EQ(rig.pose(2), 0.003);
  for (int k = 0; k < 10; ++k) rig.step(truth.measure(0.0, 0.0, 0.0));
  EXPECT_NEAR(rig.pose(0), 0.0, 1e-12);
  ASSERT_TRUE(rig.harness().activate().is_ok());
  EXPECT_EQ(rig.pose(0), 0.001);
  EXPECT_EQ(rig.pose(1), -0.002);
  EXPECT_EQ(rig.pose(2), 0.003);
}

TEST(Glsdc, NonFiniteMeasurementFaults) {
  Rig rig("model: hall", hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  std::vector<double> y(4, 0.1);
  y[2] = std::nan("");
  EXPECT_EQ(rig.step(y), StepStatus::fault);
  EXPECT_STREQ(rig.block().fault_reason(), "non-finite measurement");
  y[2] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(rig.step(y), StepStatus::fault);
}

TEST(Glsdc, SingularNormalMatrixHoldsTheEstimate) {
  // At the field extremum of kFieldExtremumModels H'WH has zero x and y columns: the update
  // must be skipped and the estimate held.
  const std::string& models = kFieldExtremumModels;
  Rig rig(params_with_initial(kQuarterPitch, kQuarterPitch, 0.0), models);
  ASSERT_TRUE(rig.ok());
  std::vector<double> y(4);
  const double state[3] = {kQuarterPitch + 0.001, kQuarterPitch - 0.001, 0.0};
  rig.model().evaluate(state, y.data());
  EXPECT_EQ(rig.step(y), StepStatus::ok);
  EXPECT_EQ(rig.pose(0), kQuarterPitch);
  EXPECT_EQ(rig.pose(1), kQuarterPitch);
  EXPECT_EQ(rig.pose(2), 0.0);
  EXPECT_EQ(rig.block().singular_skips(), 1u);
}


// ---------------------------------------------------------------------------------------
// One tick is exactly the thesis iteration (Appendix B/C), checked against an independent
// Gauss-Newton step computed here from the model's public interface.

struct GaussNewtonStep {
  Eigen::Vector3d dz;
  double cost_before = 0.0;
  double cost_after = 0.0;
};

GaussNewtonStep reference_step(const MeasurementModel& model, const std::vector<double>& y,
                               const Eigen::Vector3d& z, double sigma) {
  const std::size_t m = model.channels().size();
  std::vector<double> f(m), H(m * 3), f1(m);
  model.jacobian(z.data(), f.data(), H.data());
  Eigen::MatrixXd Hm(m, 3);
  Eigen::VectorXd dy(m);
  for (std::size_t i = 0; i < m; ++i) {
    for (int k = 0; k < 3; ++k) Hm(static_cast<Eigen::Index>(i), k) = H[i * 3 + static_cast<std::size_t>(k)];
    dy(static_cast<Eigen::Index>(i)) = y[i] - f[i];
  }
  const double w = 1.0 / (sigma * sigma);
  GaussNewtonStep s;
  s.dz = (Hm.transpose() * w * Hm).inverse() * (Hm.transpose() * w * dy);
  s.cost_before = w * dy.squaredNorm();
  const Eigen::Vector3d z1 = z + s.dz;
  model.evaluate(z1.data(), f1.data());
  for (std::size_t i = 0; i < m; ++i) s.cost_after += w * (y[i] - f1[i]) * (y[i] - f1[i]);
  return s;
}

TEST(GlsdcIteration, OneTickIsOneGaussNewtonStepWithThesisBackoff) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  const std::vector<double> y = truth.measure(0.0, 0.0, 0.0);
  int full_steps = 0;
  int backed_off = 0;
  for (double start_mm : {0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0}) {
    const Eigen::Vector3d z0(start_mm * 1e-3, -0.7 * start_mm * 1e-3, 0.002);
    Rig rig(params_with_initial(z0(0), z0(1), z0(2)), hall_model("hall", "[1, 5]"));
    ASSERT_TRUE(rig.ok());
    const GaussNewtonStep ref = reference_step(rig.model(), y, z0, 1e-3);
    ASSERT_EQ(rig.step(y), StepStatus::ok);
    const bool backoff = ref.cost_after > ref.cost_before;
    const Eigen::Vector3d expected = backoff ? Eigen::Vector3d(z0 + 0.2 * ref.dz) : Eigen::Vector3d(z0 + ref.dz);
    EXPECT_EQ(rig.block().backoffs(), backoff ? 1u : 0u) << start_mm;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(rig.pose(k), expected(k), 1e-12) << start_mm;
    (backoff ? backed_off : full_steps) += 1;
  }
  // Both branches of the rule were exercised.
  EXPECT_GT(full_steps, 0);
  EXPECT_GT(backed_off, 0);
}

TEST(GlsdcIteration, MoreIterationsPerTickConvergeInFewerTicks) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  const std::vector<double> y = truth.measure(0.0, 0.0, 0.0);
  auto ticks_to_converge = [&](const std::string& extra) {
    Rig rig(params_with_initial(0.0015, -0.001, 0.001, extra), hall_model("hall", "[1, 5]"));
    for (int k = 1; k <= 50; ++k) {
      rig.step(y);
      if (std::abs(rig.pose(0)) < 1e-12 && std::abs(rig.pose(1)) < 1e-12 && std::abs(rig.pose(2)) < 1e-11)
        return k;
    }
    return 1000;
  };
  const int one = ticks_to_converge("");
  const int five = ticks_to_converge("iterations: 5\n");
  std::printf("ticks to 1e-12 m: iterations 1 -> %d, iterations 5 -> %d\n", one, five);
  EXPECT_LE(one, 10);
  EXPECT_EQ(five, 1);
}

// ---------------------------------------------------------------------------------------
// Brief test 2: noise-free convergence from a grid of starts (estimator model == sim model).

/// Ticks until every pose error is below 1e-9 m (theta: 1e-9 m at a 0.1 m lever), or -1.
int ticks_to_truth(Rig& rig, const std::vector<double>& y, const double truth_pose[3], int max_ticks) {
  for (int k = 1; k <= max_ticks; ++k) {
    if (rig.step(y) != StepStatus::ok) return -1;
    if (std::abs(rig.pose(0) - truth_pose[0]) < 1e-9 && std::abs(rig.pose(1) - truth_pose[1]) < 1e-9 &&
        std::abs(rig.pose(2) - truth_pose[2]) < 1e-8)
      return k;
  }
  return -1;
}

struct GridResult {
  int runs = 0;
  int failures = 0;
  int worst_ticks = 0;
};

/// Starts on a grid x grid lattice over [-reach, reach]^2 around each truth pose, each with the
/// theta offsets given; counts the starts that do not reach the truth within max_ticks.
GridResult run_grid(const std::vector<std::array<double, 3>>& truth_poses, double reach, int grid,
                    const std::vector<double>& theta_offsets, int max_ticks, bool two_dof,
                    bool sensor_c) {
  Truth truth("[1, 5]", sensor_c);
  EXPECT_TRUE(truth.ok());
  const std::string models = hall_model("hall", "[1, 5]", sensor_c);
  GridResult result;
  for (const auto& tp : truth_poses) {
    const std::vector<double> y = truth.measure(tp[0], tp[1], tp[2]);
    for (int i = 0; i < grid; ++i) {
      for (int j = 0; j < grid; ++j) {
        for (double dth : theta_offsets) {
          const double dx = -reach + 2.0 * reach * i / (grid - 1);
          const double dy = -reach + 2.0 * reach * j / (grid - 1);
          Rig rig(params_with_initial(tp[0] + dx, tp[1] + dy, tp[2] + dth,
                                      two_dof ? "mode: 2dof\n" : ""),
                  models, sensor_c, two_dof);
          if (!rig.ok()) return result;
          if (two_dof) rig.set_theta(tp[2]);
          const int ticks = ticks_to_truth(rig, y, tp.data(), max_ticks);
          ++result.runs;
          if (ticks < 0) {
            ++result.failures;
            std::printf("  no convergence: truth (%.4f, %.4f, %.4f) start offset (%.2f mm, %.2f mm, %.1f mrad)\n",
                        tp[0], tp[1], tp[2], dx * 1e3, dy * 1e3, dth * 1e3);
          }
          result.worst_ticks = std::max(result.worst_ticks, ticks);
        }
      }
    }
  }
  return result;
}

std::vector<std::array<double, 3>> random_truth_poses(int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> position(-kPitch / 2, kPitch / 2);
  std::uniform_real_distribution<double> rotation(-0.005, 0.005);
  std::vector<std::array<double, 3>> poses;
  for (int i = 0; i < n; ++i) poses.push_back({position(rng), position(rng), rotation(rng)});
  return poses;
}

TEST(GlsdcConvergence, TwoDofFromEveryStartWithinAQuarterPitch) {
  // theta known (the thesis's 2-DOF mode, theta from the laser): x is seen by the quadrature
  // pair b1, d2 (12.7 mm = l/4 apart) and y by a1, c1 (190.5 mm = 3.75 l apart), so each axis
  // is a unimodal problem over more than a quarter pitch. Margin 0: the whole closed square
  // |dx|, |dy| <= l/4 converges (the measured basin reaches about 16 mm, see README).
  const GridResult r = run_grid(random_truth_poses(12, 7), kQuarterPitch, 9, {0.0}, 10, true, false);
  std::printf("2dof, 12 truth poses x 81 starts within +-12.7 mm: %d/%d failures, worst %d ticks\n",
              r.failures, r.runs, r.worst_ticks);
  EXPECT_EQ(r.runs, 12 * 81);
  EXPECT_EQ(r.failures, 0);
  EXPECT_LE(r.worst_ticks, 10);
}

TEST(GlsdcConvergence, ThreeDofTwoSensorsAtTheOrigin) {
  // With two sensors x and theta come only from b1 and d2, a square sub-problem: each channel
  // must start on the same monotone branch of its field as the truth. The branch of
  // alpha sin + beta sin 5 (beta/alpha = -0.094) ends 24 degrees before the crest, at +-66 degrees
  // = +-9.3 mm from a zero crossing; at the origin the sensors sit at +-45 degrees, leaving
  // 21 degrees = 2.96 mm, minus the 0.48 mm that a 5 mrad theta error moves a sensor 95 mm out.
  // Measured: every start within +-2.0 mm converges; 2.5 mm does not (4 of 147).
  const GridResult r = run_grid({{0.0, 0.0, 0.0}}, 0.002, 9, {-0.005, 0.0, 0.005}, 15, false, false);
  std::printf("3dof 2 sensors, origin, starts within +-2 mm x +-5 mrad: %d/%d failures, worst %d ticks\n",
              r.failures, r.runs, r.worst_ticks);
  EXPECT_EQ(r.failures, 0);
  EXPECT_LE(r.worst_ticks, 15);
}

TEST(GlsdcConvergence, ThreeDofThreeSensorsFromEveryStartWithinAQuarterPitchAtTheOrigin) {
  // Sensor C at (+95.25, +6.35) mm sees theta through the Y field as A and B do through X, so
  // the x/theta trade-off that traps two sensors disappears: every start within the closed
  // quarter-pitch square (margin 0) and +-5 mrad converges at the origin.
  const GridResult r = run_grid({{0.0, 0.0, 0.0}}, kQuarterPitch, 9, {-0.005, 0.0, 0.005}, 25, false, true);
  std::printf("3dof 3 sensors, origin, starts within +-12.7 mm x +-5 mrad: %d/%d failures, worst %d ticks\n",
              r.failures, r.runs, r.worst_ticks);
  EXPECT_EQ(r.failures, 0);
  EXPECT_LE(r.worst_ticks, 25);
}

TEST(GlsdcConvergence, ThreeDofTwoSensorsHasAWrongMinimumInsideAQuarterPitch) {
  // Why the quarter-pitch promise cannot hold for 3-DOF with two sensors: from (-4.85, -4.85) mm
  // the first step trades x against theta and the iteration settles in a stationary point with
  // a large residual (the thesis's "wrong minimum" for multi-mm steps).
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  const std::vector<double> y = truth.measure(0.0, 0.0, 0.0);
  Rig rig(params_with_initial(-0.00485, -0.00485, 0.0), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  for (int k = 0; k < 100; ++k) rig.step(y);
  const double x = rig.pose(0), yy = rig.pose(1), th = rig.pose(2);
  for (int k = 0; k < 20; ++k) rig.step(y);
  std::printf("wrong minimum: x %.4f mm, y %.4f mm, theta %.3f mrad, cost %.4g\n", x * 1e3, yy * 1e3,
              th * 1e3, rig.cost());
  EXPECT_GT(rig.cost(), 1e4);  // residual ~ 0.3 V per channel: not the truth
  EXPECT_NEAR(rig.pose(0), x, 1e-9);
  EXPECT_NEAR(rig.pose(2), th, 1e-8);
  EXPECT_GT(std::abs(th), 0.02);
}

// ---------------------------------------------------------------------------------------
// Brief test 3: Fig. 36, a 200 um Y step without noise, started at the previous pose.

TEST(GlsdcFig36, TwoHundredMicronYStep) {
  HallSetup setup;
  ASSERT_TRUE(setup.ok());
  auto& [truth, rig] = setup;
  const std::vector<double> before = truth.measure(0.0, 0.0, 0.0);
  for (int k = 0; k < 3; ++k) rig.step(before);
  EXPECT_NEAR(rig.cost(), 0.0, 1e-20);
  const std::vector<double> after = truth.measure(0.0, 200e-6, 0.0);
  std::printf("sample   x [um]        y [um]          theta [urad]   cost\n");
  std::vector<double> ys, xs, ths, costs;
  for (int k = 1; k <= 6; ++k) {
    rig.step(after);
    xs.push_back(rig.pose(0));
    ys.push_back(rig.pose(1));
    ths.push_back(rig.pose(2));
    costs.push_back(rig.cost());
    std::printf("%4d   %+.6f   %.6f   %+.6f   %.3g\n", k, xs.back() * 1e6, ys.back() * 1e6,
                ths.back() * 1e6, costs.back());
  }
  // Fig. 36 shows J settling in ~3 samples; an independent simulation gave 199.8 um after
  // sample 1, 200.000 um after 2, J ~ 1e-20 by 3, small transient coupling into x and theta on
  // sample 1.
  EXPECT_NEAR(ys[0], 200e-6, 1e-6);
  EXPECT_NEAR(ys[1], 200e-6, 1e-9);
  EXPECT_NEAR(ys[2], 200e-6, 1e-12);
  EXPECT_LT(costs[2], 1e-12);
  EXPECT_GT(costs[0], costs[1]);
  EXPECT_LT(std::abs(xs[0]), 1e-6);
  EXPECT_LT(std::abs(ths[0]), 50e-6);
  EXPECT_LT(std::abs(ths[2]), 1e-12);
}

// ---------------------------------------------------------------------------------------
// Brief test 4: with 1 mV noise the scatter of the estimate is R = (H'WH)^-1.

void check_noise_matches_covariance(const std::array<double, 3>& pose, unsigned seed) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  Rig rig(params_with_initial(pose[0], pose[1], pose[2]), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  const std::vector<double> clean = truth.measure(pose[0], pose[1], pose[2]);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-3);
  std::vector<double> y(clean.size());
  constexpr int kTicks = 2000;
  double sum[3] = {}, sum_sq[3] = {}, r_diag[3] = {};
  for (int k = 0; k < 50 + kTicks; ++k) {
    for (std::size_t i = 0; i < y.size(); ++i) y[i] = clean[i] + noise(rng);
    ASSERT_EQ(rig.step(y), StepStatus::ok);
    if (k < 50) continue;
    for (int a = 0; a < 3; ++a) {
      const double e = rig.pose(a) - pose[static_cast<std::size_t>(a)];
      sum[a] += e;
      sum_sq[a] += e * e;
      r_diag[a] += rig.covariance(a, a) / kTicks;
    }
  }
  const char* names[3] = {"x [um]", "y [um]", "theta [urad]"};
  for (int a = 0; a < 3; ++a) {
    const double mean = sum[a] / kTicks;
    const double std_dev = std::sqrt((sum_sq[a] - kTicks * mean * mean) / (kTicks - 1));
    const double predicted = std::sqrt(r_diag[a]);
    std::printf("pose (%.4f, %.4f, %.4f): %-13s sample std %.3f, sqrt(R) %.3f, ratio %.3f\n",
                pose[0], pose[1], pose[2], names[a], std_dev * 1e6, predicted * 1e6, std_dev / predicted);
    EXPECT_NEAR(std_dev / predicted, 1.0, 0.10) << names[a];
  }
}

TEST(GlsdcNoise, SampleStdMatchesCovarianceAtTheOrigin) { check_noise_matches_covariance({0.0, 0.0, 0.0}, 11); }

TEST(GlsdcNoise, SampleStdMatchesCovarianceElsewhere) {
  check_noise_matches_covariance({0.0061, -0.0143, 0.002}, 12);
}

// ---------------------------------------------------------------------------------------
// Brief test 5: open-loop traverse with the richer true field.

struct TraverseResult {
  double final_x_error = 0.0;
  double max_x_error = 0.0;
  double max_y_error = 0.0;
  double max_theta_error = 0.0;
  double static_final_x_error = 0.0;  ///< noise-free, converged at rest at the final pose
};

/// 150 mm ramp in x at 50 mm/s sampled at 800 Hz (2400 ticks), y = theta = 0, 1 mV noise;
/// the truth field has harmonics [1,3,5,7,9], the estimator `estimator_harmonics`.
TraverseResult traverse(const std::string& mode, bool sensor_c, const std::string& estimator_harmonics) {
  Truth truth("[1, 3, 5, 7, 9]", sensor_c);
  EXPECT_TRUE(truth.ok());
  const std::string models = hall_model("hall", estimator_harmonics, sensor_c);
  Rig rig("model: hall\nmode: " + mode, models, sensor_c);
  TraverseResult r;
  if (!rig.ok()) return r;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 1e-3);
  constexpr double kSpeed = 0.050;  // m/s
  constexpr double kLength = 0.150;
  const int ticks = static_cast<int>(std::lround(kLength / kSpeed * kRateHz));
  for (int k = 1; k <= ticks; ++k) {
    const double x = kSpeed * k / kRateHz;
    std::vector<double> y = truth.measure(x, 0.0, 0.0);
    for (double& v : y) v += noise(rng);
    EXPECT_EQ(rig.step(y), StepStatus::ok);
    r.final_x_error = rig.pose(0) - x;
    r.max_x_error = std::max(r.max_x_error, std::abs(r.final_x_error));
    r.max_y_error = std::max(r.max_y_error, std::abs(rig.pose(1)));
    r.max_theta_error = std::max(r.max_theta_error, std::abs(rig.pose(2)));
  }
  Rig at_rest("model: hall\nmode: " + mode + "\ninitial: [0.15, 0, 0]", models, sensor_c);
  const std::vector<double> y = truth.measure(kLength, 0.0, 0.0);
  for (int k = 0; k < 30; ++k) at_rest.step(y);
  r.static_final_x_error = at_rest.pose(0) - kLength;
  std::printf("traverse %s, %d sensors, estimator %s: final x error %.2f um (static model error "
              "there %.2f um); max |error| x %.2f um, y %.2f um, theta %.2f urad\n",
              mode.c_str(), sensor_c ? 3 : 2, estimator_harmonics.c_str(), r.final_x_error * 1e6,
              r.static_final_x_error * 1e6, r.max_x_error * 1e6, r.max_y_error * 1e6,
              r.max_theta_error * 1e6);
  return r;
}

TEST(GlsdcTraverse, RampWithTheEstimatorModelEqualToTheTruth) {
  // Tracking alone (62.5 um per tick, warm start) costs nothing: with the true harmonics in the
  // estimator the error is the measurement noise.
  for (const auto& [mode, sensor_c] : {std::pair<std::string, bool>{"2dof", false}, {"3dof", true}}) {
    const TraverseResult r = traverse(mode, sensor_c, "[1, 3, 5, 7, 9]");
    EXPECT_LT(std::abs(r.final_x_error), 50e-6) << mode;
    EXPECT_LT(r.max_x_error, 50e-6) << mode;
    EXPECT_NEAR(r.static_final_x_error, 0.0, 1e-9) << mode;
  }
  // Two sensors in 3dof: no slip, but near the field crests (sigma_theta up to 540 urad) the
  // 1 mV noise alone throws x by millimetres.
  const TraverseResult r = traverse("3dof", false, "[1, 3, 5, 7, 9]");
  EXPECT_LT(std::abs(r.final_x_error), 50e-6);
  EXPECT_LT(r.max_x_error, kQuarterPitch);
}

TEST(GlsdcTraverse, StaticModelErrorOfTheHarmonics15Model) {
  // Noise-free, at rest: where the [1,5] estimator puts a platen that sits in the [1..9] field,
  // over one pitch of x (2dof, theta = 0). This is the accuracy limit of the thesis's model at
  // a 2 mm gap, and the reason the traverse below cannot meet 50 um.
  Truth truth("[1, 3, 5, 7, 9]");
  ASSERT_TRUE(truth.ok());
  double worst = 0.0;
  for (int i = 0; i < 64; ++i) {
    const double x = kPitch * i / 64.0;
    Rig rig(params_with_initial(x, 0.0, 0.0, "mode: 2dof\n"), hall_model("hall", "[1, 5]"));
    ASSERT_TRUE(rig.ok());
    const std::vector<double> y = truth.measure(x, 0.0, 0.0);
    for (int k = 0; k < 30; ++k) rig.step(y);
    worst = std::max(worst, std::abs(rig.pose(0) - x));
  }
  std::printf("static x error of the [1,5] model in the [1..9] field (2 mm gap, 2dof): max %.1f um\n",
              worst * 1e6);
  EXPECT_GT(worst, 150e-6);
  EXPECT_LT(worst, 250e-6);
}

TEST(GlsdcTraverse, RampTwoDofWithTheHarmonics15Model) {
  // The [1,5] model misses the 3rd (38 mV), 7th and 9th (68 mV) harmonics of the 2 mm field
  // (max 108 mV): a systematic, periodic position error of up to 233 um over a pitch (README),
  // 191 um at the end point. The brief's "< 50 um" cannot hold at a 2 mm gap; what must hold is
  // no cycle slip and a final error equal to the static model error within the noise.
  const TraverseResult r = traverse("2dof", false, "[1, 5]");
  EXPECT_LT(r.max_x_error, kQuarterPitch);  // no cycle slip
  EXPECT_LT(r.max_x_error, 0.25e-3);        // bounded by the static model error (233 um)
  EXPECT_NEAR(r.final_x_error, r.static_final_x_error, 10e-6);
}

TEST(GlsdcTraverse, RampThreeDofThreeSensorsWithTheHarmonics15Model) {
  const TraverseResult r = traverse("3dof", true, "[1, 5]");
  EXPECT_LT(r.max_x_error, kQuarterPitch);  // no cycle slip
  EXPECT_LT(r.max_x_error, 0.5e-3);
  EXPECT_NEAR(r.final_x_error, r.static_final_x_error, 20e-6);
}

TEST(GlsdcTraverse, RampThreeDofTwoSensorsWithTheHarmonics15ModelSlips) {
  // Characterisation of the thesis's 3-DOF two-sensor set-up (it failed there too):
  // x and theta come from b1 and d2 alone, so the ~100 mV model error maps into mrad of theta
  // and mm of x near the crests, and the estimate slips by pitches.
  const TraverseResult r = traverse("3dof", false, "[1, 5]");
  EXPECT_GT(r.max_x_error, kQuarterPitch);
}

// ---------------------------------------------------------------------------------------
// Brief test 6: 2dof mode and three sensors.

TEST(GlsdcModes, TwoDofUsesTheThetaInputAndZeroesItsCovariance) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  const double theta = 0.01;
  Rig rig(params_with_initial(0.004, -0.003, 0.0, "mode: 2dof\n"), hall_model("hall", "[1, 5]"), false, true);
  ASSERT_TRUE(rig.ok());
  rig.set_theta(theta);
  const std::vector<double> y = truth.measure(0.0021, 0.0035, theta);
  int k = 0;
  while (k < 20 && !(std::abs(rig.pose(0) - 0.0021) < 1e-12 && std::abs(rig.pose(1) - 0.0035) < 1e-12)) {
    rig.step(y);
    ++k;
  }
  std::printf("2dof with theta input: converged in %d ticks\n", k);
  EXPECT_LT(k, 20);
  EXPECT_EQ(rig.pose(2), theta);
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(rig.covariance(2, a), 0.0);
    EXPECT_EQ(rig.covariance(a, 2), 0.0);
  }
  EXPECT_GT(rig.covariance(0, 0), 0.0);
  EXPECT_GT(rig.covariance(1, 1), 0.0);
}

TEST(GlsdcModes, TwoDofWithoutThetaInputUsesInitialTheta) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  Rig rig(params_with_initial(0.001, 0.001, -0.003, "mode: 2dof\n"), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  const std::vector<double> y = truth.measure(0.0, 0.0, -0.003);
  for (int k = 0; k < 10; ++k) rig.step(y);
  EXPECT_NEAR(rig.pose(0), 0.0, 1e-12);
  EXPECT_NEAR(rig.pose(1), 0.0, 1e-12);
  EXPECT_EQ(rig.pose(2), -0.003);
}

TEST(GlsdcModes, ThreeSensorsConvergeAndBoundTheRotationNoise) {
  // With two sensors sigma_theta depends strongly on x (b1 or d2 near a field crest);
  // a third sensor bounds it. Scan x over a pitch and compare the largest sqrt(R_thth).
  Truth truth2("[1, 5]");
  Truth truth3("[1, 5]", true);
  ASSERT_TRUE(truth2.ok() && truth3.ok());
  double worst2 = 0.0, worst3 = 0.0;
  for (int i = 0; i < 64; ++i) {
    const double x = kPitch * i / 64.0;
    Rig rig2(params_with_initial(x, 0.0, 0.0), hall_model("hall", "[1, 5]"));
    Rig rig3(params_with_initial(x + 0.001, -0.001, 0.002), hall_model("hall", "[1, 5]", true), true);
    ASSERT_TRUE(rig2.ok() && rig3.ok());
    rig2.step(truth2.measure(x, 0.0, 0.0));
    const std::vector<double> y3 = truth3.measure(x, 0.0, 0.0);
    const double truth_pose[3] = {x, 0.0, 0.0};
    EXPECT_GT(ticks_to_truth(rig3, y3, truth_pose, 15), 0) << x;
    worst2 = std::max(worst2, std::sqrt(rig2.covariance(2, 2)));
    worst3 = std::max(worst3, std::sqrt(rig3.covariance(2, 2)));
  }
  std::printf("max sigma_theta over a pitch of x (1 mV): 2 sensors %.1f urad, 3 sensors %.1f urad\n",
              worst2 * 1e6, worst3 * 1e6);
  EXPECT_LT(worst3, 0.5 * worst2);
}

// ---------------------------------------------------------------------------------------

TEST(GlsdcRealTime, StepDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  HallSetup setup;
  ASSERT_TRUE(setup.ok());
  auto& [truth, rig] = setup;
  std::vector<std::vector<double>> inputs;
  for (int i = 0; i < 100; ++i) inputs.push_back(truth.measure(1e-4 * i, -5e-5 * i, 1e-5 * i));
  EXPECT_EQ(allocations_over_ticks(rig, inputs, 10000, [] {}), 0u);
}

// --- estimator state (hot swap) and invalid_measurement ---------------------------------

bool positive_definite(const std::vector<double>& c) {
  Eigen::Matrix3d p;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p(i, j) = c[static_cast<std::size_t>(3 * i + j)];
  return p.allFinite() && p == p.transpose() && Eigen::LLT<Eigen::Matrix3d>(p).info() == Eigen::Success;
}

/// Noisy measurements of a slow planar motion (1 mV channel noise, fixed seed).
std::vector<std::vector<double>> noisy_path(Truth& truth, int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-3);
  std::vector<std::vector<double>> out;
  for (int k = 0; k < n; ++k) {
    std::vector<double> y = truth.measure(1e-3 * std::sin(0.01 * k), 5e-4 * std::cos(0.013 * k), 2e-3 * std::sin(0.007 * k));
    for (double& v : y) v += noise(rng);
    out.push_back(std::move(y));
  }
  return out;
}

TEST(GlsdcState, LayoutAndExportBeforeTheFirstSolve) {
  Rig rig(params_with_initial(0.001, -0.002, 0.003), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  const StateLayout layout = rig.estimator().state_layout();
  ASSERT_EQ(layout.size(), 3u);
  EXPECT_EQ(layout.elements[0].name, "x");
  EXPECT_EQ(layout.elements[0].unit, "m");
  EXPECT_EQ(layout.elements[1].name, "y");
  EXPECT_EQ(layout.elements[1].unit, "m");
  EXPECT_EQ(layout.elements[2].name, "theta_z");
  EXPECT_EQ(layout.elements[2].unit, "rad");
  EXPECT_TRUE(layout.covariance);
  EXPECT_EQ(rig.estimator().innovation_size(), 0u) << "a batch solver has no innovation";
  double nu = 0.0, s = 0.0;
  EXPECT_FALSE(rig.estimator().innovation(&nu, &s));
  // Before any solve: the initial pose and "unknown" (1 m^2, 1 m^2, 1 rad^2), positive definite.
  const auto e = lode::testing::export_state_of(rig.estimator());
  EXPECT_EQ(e.values, (std::vector<double>{0.001, -0.002, 0.003}));
  EXPECT_EQ(e.covariance, (std::vector<double>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
}

TEST(GlsdcState, ExportIsTheWarmStartAndThePublishedR) {
  HallSetup setup;
  ASSERT_TRUE(setup.ok());
  auto& [truth, rig] = setup;
  for (const auto& y : noisy_path(truth, 20, 5)) ASSERT_EQ(rig.step(y), StepStatus::ok);
  const auto e = lode::testing::export_state_of(rig.estimator());
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(e.values[static_cast<std::size_t>(a)], rig.pose(a));
    for (int b = 0; b < 3; ++b) {
      // The published R symmetrised (it is symmetric only to rounding).
      EXPECT_EQ(e.covariance[static_cast<std::size_t>(3 * a + b)], 0.5 * (rig.covariance(a, b) + rig.covariance(b, a)));
      EXPECT_NEAR(e.covariance[static_cast<std::size_t>(3 * a + b)], rig.covariance(a, b),
                  1e-12 * std::sqrt(rig.covariance(a, a) * rig.covariance(b, b)));
    }
  }
  EXPECT_TRUE(positive_definite(e.covariance));

  // 2dof: theta is not estimated; its row and column export as (1 rad)^2 on the diagonal.
  Rig two(params_with_initial(0.0, 0.0, 0.002, "mode: 2dof\n"), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(two.ok());
  for (int k = 0; k < 5; ++k) ASSERT_EQ(two.step(truth.measure(1e-4, 2e-4, 0.002)), StepStatus::ok);
  const auto e2 = lode::testing::export_state_of(two.estimator());
  EXPECT_EQ(two.covariance(2, 2), 0.0) << "the published R keeps theta's row and column 0";
  EXPECT_EQ(e2.covariance[8], Glsdc::kUnknownVariance);
  EXPECT_EQ(e2.covariance[2], 0.0);
  EXPECT_EQ(e2.covariance[6], 0.0);
  EXPECT_EQ(e2.covariance[0], two.covariance(0, 0));
  EXPECT_TRUE(positive_definite(e2.covariance));
}

TEST(GlsdcState, ExportImportReproducesTheNextStepsBitForBit) {
  Truth truth("[1, 5]", true);
  ASSERT_TRUE(truth.ok());
  for (const char* extra : {"", "iterations: 3\n"}) {
    SCOPED_TRACE(extra);
    Rig a(std::string("model: hall\n") + extra, hall_model("hall", "[1, 5]", true), true);
    Rig b(std::string("model: hall\n") + extra, hall_model("hall", "[1, 5]", true), true);
    ASSERT_TRUE(a.ok() && b.ok());
    const auto path = noisy_path(truth, 120, 9);
    for (int k = 0; k < 100; ++k) ASSERT_EQ(a.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
    const auto e = lode::testing::export_state_of(a.estimator());
    const std::uint8_t present[3] = {1, 1, 1};
    b.estimator().import_state(e.values.data(), e.covariance.data(), present);
    EXPECT_EQ(lode::testing::export_state_of(b.estimator()).values, e.values);
    for (int k = 100; k < 120; ++k) {
      ASSERT_EQ(a.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
      ASSERT_EQ(b.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
      for (int i = 0; i < 3; ++i) {
        ASSERT_EQ(a.pose(i), b.pose(i)) << "k = " << k;
        for (int j = 0; j < 3; ++j) ASSERT_EQ(a.covariance(i, j), b.covariance(i, j)) << "k = " << k;
      }
      ASSERT_EQ(a.cost(), b.cost());
    }
  }
}

TEST(GlsdcState, PresentMaskKeepsTheInitialPose) {
  Rig rig(params_with_initial(0.001, -0.002, 0.003), hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok());
  const double values[3] = {0.004, std::nan(""), 0.006};
  const std::uint8_t present[3] = {1, 1, 0};
  rig.estimator().import_state(values, nullptr, present);
  EXPECT_EQ(lode::testing::export_state_of(rig.estimator()).values, (std::vector<double>{0.004, -0.002, 0.003}))
      << "absent or non-finite: the configured initial pose";
  EXPECT_TRUE(positive_definite(lode::testing::export_state_of(rig.estimator()).covariance));
}

TEST(GlsdcInvalid, PropagateMakesTheCycleNaNAndKeepsTheWarmStart) {
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  Rig rig("model: hall\ninvalid_measurement: propagate", hall_model("hall", "[1, 5]"));
  Rig reference("model: hall", hall_model("hall", "[1, 5]"));
  ASSERT_TRUE(rig.ok() && reference.ok());
  const auto path = noisy_path(truth, 40, 13);
  for (int k = 0; k < 30; ++k) {
    ASSERT_EQ(rig.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
    ASSERT_EQ(reference.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
  }
  const auto before = lode::testing::export_state_of(rig.estimator());
  std::vector<double> bad = path[30];
  bad[1] = std::nan("");
  ASSERT_EQ(rig.step(bad), StepStatus::ok);
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(std::isnan(rig.pose(i))) << i;
    for (int j = 0; j < 3; ++j) EXPECT_TRUE(std::isnan(rig.covariance(i, j)));
  }
  EXPECT_TRUE(std::isnan(rig.cost()));
  const auto during = lode::testing::export_state_of(rig.estimator());
  EXPECT_EQ(during.values, before.values) << "the warm start is kept";
  EXPECT_EQ(during.covariance, before.covariance);
  // The next valid cycle continues exactly as if the bad one had not happened.
  for (int k = 31; k < 40; ++k) {
    ASSERT_EQ(rig.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
    ASSERT_EQ(reference.step(path[static_cast<std::size_t>(k)]), StepStatus::ok);
    for (int i = 0; i < 3; ++i) ASSERT_EQ(rig.pose(i), reference.pose(i)) << "k = " << k;
  }
  // The default is unchanged: fault.
  bad[1] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(reference.step(bad), StepStatus::fault);
  EXPECT_STREQ(reference.block().fault_reason(), "non-finite measurement");

  // 2dof: a NaN theta input is propagated the same way.
  Rig two("model: hall\nmode: 2dof\ninvalid_measurement: propagate", hall_model("hall", "[1, 5]"), false, true);
  ASSERT_TRUE(two.ok());
  two.set_theta(std::nan(""));
  ASSERT_EQ(two.step(truth.measure(0.0, 0.0, 0.0)), StepStatus::ok);
  EXPECT_TRUE(std::isnan(two.pose(0)));
}

TEST(GlsdcState, ExportImportDoNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  HallSetup setup;
  ASSERT_TRUE(setup.ok());
  auto& [truth, rig] = setup;
  const auto path = noisy_path(truth, 100, 17);
  double values[3], covariance[9], nu = 0.0, s = 0.0;
  const std::uint8_t present[3] = {1, 1, 1};
  EXPECT_EQ(allocations_over_ticks(rig, path, 2000,
                                   [&] {
                                     rig.estimator().export_state(values, covariance);
                                     rig.estimator().import_state(values, covariance, present);
                                     (void)rig.estimator().innovation(&nu, &s);
                                   }),
            0u);
}

}  // namespace
}  // namespace lode::plugins
