// estimator.ekf: equality with an independent EKF written out for the Sensors 2016 suspension
// (analytic Jacobian of eq. 33 with the mass), numerical vs analytic Jacobian, the rk4 process model
// (no analytic Jacobian), faults, configuration errors and no allocation in step().
#include "ekf.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "estimator/testing/harness_setup.hpp"
#include "estimator/testing/state_handover.hpp"
#include "estimator/testing/suspension_estimator.hpp"
#include "hall_polynomial.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/state_export.hpp"

namespace {

using lode::estimator_testing::kHallDistanceNoise;
using lode::estimator_testing::started;
using lode::estimator_testing::suspension_estimator;

constexpr double kDt = 0.5e-3;

// The Euler model (eq. 33 with the mass) of config/suspension_ukf.yaml, and its Jacobian.
struct Plant {
  double m = 6.0e-3, g = 9.81, a = 5.996e-9, b = 4.85e-5, decay = 165.6, gain = 61.61;
  [[nodiscard]] Eigen::Vector3d step(const Eigen::Vector3d& x, double u) const {
    const double d = x(0);
    const double acc = g - (a / std::pow(d, 4) + b * x(2) / (d * d)) / m;
    return {x(0) + kDt * x(1), x(1) + kDt * acc, x(2) + kDt * (-decay * x(2) + gain * u)};
  }
  [[nodiscard]] Eigen::Matrix3d jacobian(const Eigen::Vector3d& x) const {
    const double d = x(0);
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    F(0, 1) = kDt;
    F(1, 0) = kDt * (4 * a / std::pow(d, 5) + 2 * b * x(2) / std::pow(d, 3)) / m;
    F(1, 2) = -kDt * b / (d * d) / m;
    F(2, 2) = 1 - decay * kDt;
    return F;
  }
  [[nodiscard]] double hold_current(double d) const { return (m * g - a / std::pow(d, 4)) * d * d / b; }
};

struct Benchmark {
  std::vector<double> u, y;
  std::vector<Eigen::Vector3d> truth;
};

Benchmark make_benchmark(int cycles) {
  const Plant p;
  Benchmark bm;
  Eigen::Vector3d x(0.026, 0.0, p.hold_current(0.026));
  double u = p.hold_current(0.026) * p.decay / p.gain;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1e-4);
  for (int k = 0; k < cycles; ++k) {
    bm.truth.push_back(x);
    bm.u.push_back(u);
    bm.y.push_back(x(0) + noise(rng));
    const double ref = 0.025 + 0.0015 * std::sin(2 * M_PI * 3.0 * k * kDt);
    u = std::clamp(p.hold_current(ref) * p.decay / p.gain + 800.0 * (x(0) - ref) + 19.0 * x(1), 0.0, 5.0);
    x = p.step(x, u);
  }
  return bm;
}

const Eigen::Vector3d kQ(5.6e-8 * kDt, 1.7e-8 * kDt, 7.71e-3 * kDt);
constexpr double kR = 1.2e-7;
const Eigen::Vector3d kP0(1e-6, 1e-4, 1e-2);

/// The EKF of the file comment, written out for this model.
std::vector<Eigen::Vector3d> reference_ekf(const Benchmark& bm) {
  const Plant p;
  Eigen::Vector3d x(0.0265, 0.0, bm.truth[0](2));
  Eigen::Matrix3d P = kP0.asDiagonal();
  const Eigen::Matrix3d Q = kQ.asDiagonal();
  std::vector<Eigen::Vector3d> out;
  for (std::size_t k = 0; k < bm.y.size(); ++k) {
    if (k > 0) {
      const Eigen::Matrix3d F = p.jacobian(x);
      x = p.step(x, bm.u[k]);
      P = F * P * F.transpose() + Q;
    }
    const double S = P(0, 0) + kR;
    const Eigen::Vector3d K = P.col(0) / S;
    x += K * (bm.y[k] - x(0));
    Eigen::Matrix3d IKH = Eigen::Matrix3d::Identity();
    IKH.col(0) -= K;
    P = IKH * P * IKH.transpose() + K * kR * K.transpose();
    out.push_back(x);
  }
  return out;
}

const char* const kModels =
    "plant: {plugin: plant.suspension, mass_kg: 6.0e-3, force_b_n_m2_per_a: 4.85e-5}\n"
    "plant_rk4: {plugin: plant.suspension, mass_kg: 6.0e-3, force_b_n_m2_per_a: 4.85e-5, process_discretization: rk4}\n"
    "hall_distance: {plugin: sensor.hall_gap, output: gap}\n";

std::string block(const Benchmark& bm, const std::string& extra = "", const std::string& process = "plant") {
  return suspension_estimator(kHallDistanceNoise, bm.truth[0](2), process) + extra;
}

std::vector<Eigen::Vector3d> run_block(lode::testing::BlockHarness& h, const Benchmark& bm) {
  h.feed("measurement", {{"gap", "m"}});
  h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
  std::vector<Eigen::Vector3d> out;
  if (!h.configure() || !h.activate()) {
    ADD_FAILURE() << h.diagnostics();
    return out;
  }
  for (std::size_t k = 0; k < bm.y.size(); ++k) {
    h.input("measurement")[0] = bm.y[k];
    h.input("input")[1] = bm.u[k];
    if (h.step() != lode::StepStatus::ok) {
      ADD_FAILURE() << h.block().fault_reason();
      break;
    }
    out.emplace_back(h.output("state")[0], h.output("state")[1], h.output("state")[2]);
  }
  return out;
}

TEST(EkfBlock, EqualsTheWrittenOutEkfWithTheAnalyticJacobian) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark bm = make_benchmark(4000);
  lode::testing::BlockHarness h("estimator.ekf", block(bm), 2000.0, kModels);
  const auto ours = run_block(h, bm);
  const auto reference = reference_ekf(bm);
  ASSERT_EQ(ours.size(), reference.size());
  double worst = 0.0;
  for (std::size_t k = 0; k < ours.size(); ++k)
    worst = std::max(worst, ((ours[k] - reference[k]).array() / Eigen::Array3d(0.03, 0.05, 1.0)).abs().maxCoeff());
  EXPECT_LT(worst, 1e-9);
  EXPECT_EQ(h.describe().find("filter")->find("jacobian")->as_string(), "analytic (from the process model)");
  double sum = 0.0;
  for (std::size_t k = 1000; k < ours.size(); ++k) sum += std::pow(ours[k](0) - bm.truth[k](0), 2);
  const double rms = std::sqrt(sum / static_cast<double>(ours.size() - 1000));
  std::printf("EKF gap error rms %.2f um (measurement noise 100 um)\n", rms * 1e6);
  EXPECT_LT(rms, 30e-6);
}

TEST(EkfBlock, CentralDifferencesAgreeWithTheAnalyticJacobian) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark bm = make_benchmark(3000);
  lode::testing::BlockHarness analytic("estimator.ekf", block(bm), 2000.0, kModels);
  lode::testing::BlockHarness numerical("estimator.ekf", block(bm, "jacobian: numerical\n"), 2000.0, kModels);
  const auto a = run_block(analytic, bm);
  const auto n = run_block(numerical, bm);
  ASSERT_EQ(a.size(), n.size());
  double worst = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k)
    worst = std::max(worst, ((a[k] - n[k]).array() / Eigen::Array3d(0.03, 0.05, 1.0)).abs().maxCoeff());
  std::printf("numerical vs analytic Jacobian: worst scaled state difference %.2e\n", worst);
  EXPECT_LT(worst, 1e-7);
  EXPECT_EQ(numerical.describe().find("filter")->find("jacobian")->as_string(), "numerical (forced)");
}

TEST(EkfBlock, Rk4ProcessModelIsDifferentiatedNumerically) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark bm = make_benchmark(2000);
  lode::testing::BlockHarness h("estimator.ekf", block(bm, "", "plant_rk4"), 2000.0, kModels);
  const auto out = run_block(h, bm);
  ASSERT_EQ(out.size(), bm.y.size());
  EXPECT_EQ(h.describe().find("filter")->find("jacobian")->as_string(),
            "central differences (the model has no analytic one)");
  EXPECT_LT(std::abs(out.back()(0) - bm.truth.back()(0)), 100e-6);  // RK4 vs Euler truth: still tracks
  lode::testing::BlockHarness refused("estimator.ekf", block(bm, "jacobian: analytic\n", "plant_rk4"), 2000.0, kModels);
  refused.feed("measurement", {{"gap", "m"}});
  refused.feed("input", {{"coil_voltage", "V"}});
  EXPECT_FALSE(refused.configure());
  EXPECT_NE(refused.diagnostics().find("jacobian: the process model provides no analytic Jacobian"), std::string::npos)
      << refused.diagnostics();
}

TEST(EkfBlock, CovarianceStaysSymmetricPositive) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const Benchmark bm = make_benchmark(10000);
  lode::testing::BlockHarness h("estimator.ekf", block(bm), 2000.0, kModels);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
  ASSERT_TRUE(started(h));
  auto measurement = h.input("measurement");  // the spans, not a lookup per cycle
  auto input = h.input("input");
  const auto std_out = h.output("std");
  const auto before = lode::testing::allocation_count();
  for (std::size_t k = 0; k < bm.y.size(); ++k) {
    measurement[0] = bm.y[k];
    input[1] = bm.u[k];
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << h.block().fault_reason();
    for (std::size_t i = 0; i < 3; ++i) ASSERT_GT(std_out[i], 0.0);
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u) << "step() allocated";
  auto& ekf = dynamic_cast<lode::plugins::ExtendedEstimator&>(h.block());
  const auto& P = ekf.covariance();
  EXPECT_LT((P - P.transpose()).cwiseAbs().maxCoeff(), 1e-300 + 1e-15 * P.cwiseAbs().maxCoeff());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(P)).eigenvalues().minCoeff(), 0.0);
}

TEST(EkfBlock, FaultsOnNonFiniteMeasurement) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark bm = make_benchmark(10);
  lode::testing::BlockHarness h("estimator.ekf", block(bm), 2000.0, kModels);
  h.feed("measurement", {{"gap", "m"}});
  h.feed("input", {{"coil_voltage", "V"}});
  ASSERT_TRUE(started(h));
  h.input("measurement")[0] = NAN;
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement");
  EXPECT_EQ(h.output("state")[0], 0.0265);
}

TEST(EkfBlock, UnknownJacobianChoiceAndMissingInputAreErrors) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const Benchmark bm = make_benchmark(2);
  lode::testing::BlockHarness h("estimator.ekf", block(bm, "jacobian: symbolic\n"), 2000.0, kModels);
  h.feed("measurement", {{"gap", "m"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("jacobian"), std::string::npos) << d;
  EXPECT_NE(d.find("required input 'input' is not connected"), std::string::npos) << d;
}

constexpr const char* kStatePlugin = "estimator.ekf";
#include "estimator/testing/model_estimator_state_tests.inc"

TEST(EkfBlock, SizedAlgebraGivesTheGenericResultsBitForBit) {
  // The suspension (n = 3, m = 1) runs algebra sized at compile time; compile_time_sizes: false
  // runs the generic one. Same operations in the same order: the same bits, cycle by cycle,
  // and neither allocates in step().
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const Benchmark bm = make_benchmark(4000);
  lode::testing::BlockHarness sized("estimator.ekf", block(bm), 2000.0, kModels);
  lode::testing::BlockHarness generic("estimator.ekf", block(bm, "compile_time_sizes: false\n"), 2000.0, kModels);
  for (auto* h : {&sized, &generic}) {
    h->feed("measurement", {{"gap", "m"}});
    h->feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
    ASSERT_TRUE(started(*h));
  }
  EXPECT_TRUE(dynamic_cast<lode::plugins::ExtendedEstimator&>(sized.block()).fixed_size());
  EXPECT_FALSE(dynamic_cast<lode::plugins::ExtendedEstimator&>(generic.block()).fixed_size());
  EXPECT_EQ(sized.describe().find("filter")->find("algebra")->as_string(), "sized at compile time (n = 3, m = 1)");
  std::size_t allocations = 0;
  for (std::size_t k = 0; k < bm.y.size(); ++k) {
    for (auto* h : {&sized, &generic}) {
      h->input("measurement")[0] = bm.y[k];
      h->input("input")[1] = bm.u[k];
      allocations += lode::estimator_testing::allocations_during(
          [&] { ASSERT_EQ(h->step(), lode::StepStatus::ok) << h->block().fault_reason(); });
    }
    ASSERT_TRUE(lode::estimator_testing::same_outputs(sized, generic, {"state", "std", "innovation"}, k));
  }
  EXPECT_EQ(allocations, 0u) << "step() allocated";
  const auto& P = dynamic_cast<lode::plugins::ExtendedEstimator&>(sized.block()).covariance();
  const auto& P_generic = dynamic_cast<lode::plugins::ExtendedEstimator&>(generic.block()).covariance();
  EXPECT_EQ(P, P_generic);
}

TEST(EkfBlock, SizedAlgebraForAnHThatReadsAnInputGivesTheGenericResultsBitForBit) {
  // The Hall voltage's h reads the gap and the coil voltage, a process input: the sized cycle
  // then takes its general products with H, not the ones that leave out H's zero columns
  // when h reads the first state alone (the test above).
  LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
  const std::string models = std::string(kModels) + "hall_volts: {plugin: sensor.hall_gap}\n";
  const Benchmark bm = make_benchmark(3000);
  const std::string params = suspension_estimator(
      "measurement: hall_volts\nq: [5.6e-8, 1.7e-8, 7.71e-3]\nprocess_noise: per_second\nr: 4e-6\n", bm.truth[0](2));
  lode::testing::BlockHarness sized("estimator.ekf", params, 2000.0, models);
  lode::testing::BlockHarness generic("estimator.ekf", params + "compile_time_sizes: false\n", 2000.0, models);
  for (auto* h : {&sized, &generic}) {
    h->feed("measurement", {{"hall", "V"}});
    h->feed("input", {{"gap", "m"}, {"coil_voltage", "V"}});
    ASSERT_TRUE(started(*h));
  }
  ASSERT_TRUE(dynamic_cast<lode::plugins::ExtendedEstimator&>(sized.block()).fixed_size());
  const lode::plugins::hall::Conversion c = lode::plugins::hall::Conversion::paper();
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 2e-3);
  for (std::size_t k = 0; k < bm.y.size(); ++k) {
    const double hall_v = c.compensated_for_distance(bm.truth[k](0) * 1e3) + c.coil_v.value(bm.u[k]) + noise(rng);
    for (auto* h : {&sized, &generic}) {
      h->input("measurement")[0] = hall_v;
      h->input("input")[1] = bm.u[k];
      ASSERT_EQ(h->step(), lode::StepStatus::ok) << h->block().fault_reason();
    }
    ASSERT_TRUE(lode::estimator_testing::same_outputs(sized, generic, {"state", "std", "innovation"}, k));
  }
}

}  // namespace
