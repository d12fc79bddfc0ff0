// estimator.npo: the discrete update's error dynamics (exact = sampled continuous Eq. 15-18,
// the derived eigenvalues at the Table 2 gains, forward Euler's -3), exactness with a perfect
// model, the force-bias steady state a b / d, the composite W, M read off the process model, the
// tuning rule, the finite-difference baseline, configuration errors and no allocation in step().
#include "npo.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

namespace npo = lode::plugins::npo;

constexpr double kRateHz = 2500.0;
constexpr double kT = 1.0 / kRateHz;  // the paper's 0.4 ms
constexpr double kMass = 0.931;       // Table 1
constexpr std::array<double, 6> kM{0.931, 0.931, 0.931, 1.799e-3, 1.834e-3, 3.336e-3};

const lode::Elements kPose{{"x", "m"}, {"y", "m"}, {"z", "m"}, {"phi", "rad"}, {"theta", "rad"}, {"psi", "rad"}};
const lode::Elements kForce{{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}};
const std::string kModels = "stage: {plugin: plant.rigid_body6}\n";


#define REQUIRE_PLANT() LODE_REQUIRE_PLUGINS("plant.rigid_body6")

// ---- the per-axis design -------------------------------------------------------------------

// Exact: E = exp(A_e T). Checked against the eigen-decomposition of A_e, computed independently.
TEST(NpoDesign, ExactTransitionIsTheSampledContinuousErrorDynamics) {
  for (const auto& [m, d, a] : std::array<std::array<double, 3>, 4>{
           {{kMass, 100.0, 1e4}, {1.799e-3, 100.0, 1e4}, {kMass, 9.19e4, 440.0}, {kMass, 100.0, 1e-4}}}) {
    const npo::AxisDesign axis = npo::design_axis(m, d, a, kT, npo::Integrator::exact);
    Eigen::Matrix2d ae;
    ae << -a, 1.0, -d / m, 0.0;
    const Eigen::EigenSolver<Eigen::Matrix2d> solver(ae);
    const Eigen::Matrix2cd v = solver.eigenvectors();
    Eigen::Matrix2cd lambda = Eigen::Matrix2cd::Zero();
    for (int i = 0; i < 2; ++i) lambda(i, i) = std::exp(solver.eigenvalues()(i) * kT);
    const Eigen::Matrix2d expected = (v * lambda * v.inverse()).real();
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        EXPECT_NEAR(axis.transition(i, j), expected(i, j), 1e-9 * (std::abs(expected(i, j)) + 1e-6))
            << "m " << m << " d " << d << " a " << a << " (" << i << "," << j << ")";
      }
    }
    // The discrete eigenvalues are e^{sT} of the continuous poles.
    for (const auto& s : axis.continuous_poles) {
      const std::complex<double> z = std::exp(s * kT);
      const double distance = std::min(std::abs(z - axis.discrete_poles[0]), std::abs(z - axis.discrete_poles[1]));
      EXPECT_LT(distance, 1e-9) << "pole " << s;
    }
  }
}

// Derived for the Table 2 gains, A0 = 1e4 (SI): poles -0.0107 / -9999.99 (translation), -5.56,
// -5.46, -3.00 (rotations); exact update eigenvalues 0.9999957 and 0.0183; forward Euler -3.
TEST(NpoDesign, Table2GainsGiveTheDerivedPoles) {
  const std::array<double, 4> slow{-0.0107, -5.56, -5.46, -3.00};
  const std::array<double, 4> fast{-9999.99, -9994.0, -9995.0, -9997.0};
  const std::array<double, 4> mass{kM[0], kM[3], kM[4], kM[5]};
  for (std::size_t i = 0; i < 4; ++i) {
    const npo::AxisDesign axis = npo::design_axis(mass[i], 100.0, 1e4, kT, npo::Integrator::exact);
    const double s_slow = std::max(axis.continuous_poles[0].real(), axis.continuous_poles[1].real());
    const double s_fast = std::min(axis.continuous_poles[0].real(), axis.continuous_poles[1].real());
    std::printf("axis m = %g: poles %.5g, %.6g rad/s (ref %.4g, %.6g)\n", mass[i], s_slow, s_fast, slow[i], fast[i]);
    EXPECT_NEAR(s_slow, slow[i], 0.005 * std::abs(slow[i]));
    EXPECT_NEAR(s_fast, fast[i], 1.0);
  }
  const npo::AxisDesign translation = npo::design_axis(kMass, 100.0, 1e4, kT, npo::Integrator::exact);
  const double z_big = std::max(std::abs(translation.discrete_poles[0]), std::abs(translation.discrete_poles[1]));
  const double z_small = std::min(std::abs(translation.discrete_poles[0]), std::abs(translation.discrete_poles[1]));
  std::printf("exact: z = %.7f and %.4f (ref 0.9999957, 0.0183)\n", z_big, z_small);
  EXPECT_NEAR(z_big, 0.9999957, 1e-7);
  EXPECT_NEAR(z_small, 0.0183, 5e-5);

  const npo::AxisDesign euler = npo::design_axis(kMass, 100.0, 1e4, kT, npo::Integrator::forward_euler);
  const double z_euler = std::min(euler.discrete_poles[0].real(), euler.discrete_poles[1].real());
  std::printf("forward Euler: z = %.6f (ref 1 - aT = -3)\n", z_euler);
  EXPECT_NEAR(z_euler, -3.0, 1e-4);
  EXPECT_GT(euler.spectral_radius(), 1.0);

  const npo::AxisDesign implicit = npo::design_axis(kMass, 100.0, 1e4, kT, npo::Integrator::backward_euler);
  EXPECT_LT(implicit.spectral_radius(), 1.0);
  // det E = 1 / (1 + aT) for the backward-Euler scheme.
  EXPECT_NEAR(implicit.transition.determinant(), 1.0 / 5.0, 1e-12);
}

// S3 as a unit test: iterate the error recursion of each scheme from a 1 um / 1 um/s error.
TEST(NpoDesign, ForwardEulerDivergesWhereExactAndImplicitStayBounded) {
  const Eigen::Vector2d e0(1e-6, 1e-6);
  for (npo::Integrator integrator :
       {npo::Integrator::exact, npo::Integrator::backward_euler, npo::Integrator::forward_euler}) {
    const npo::AxisDesign axis = npo::design_axis(kMass, 100.0, 1e4, kT, integrator);
    Eigen::Vector2d e = e0;
    double largest = e.norm();
    for (int k = 0; k < 100; ++k) {
      e = axis.transition * e;
      largest = std::max(largest, e.norm());
    }
    std::printf("%s: max |e| over 100 steps = %.3g (start %.3g)\n", npo::to_string(integrator), largest, e0.norm());
    if (integrator == npo::Integrator::forward_euler) {
      EXPECT_GT(largest, 1e40 * e0.norm());  // ~3^100
    } else {
      EXPECT_LT(largest, 2.0 * e0.norm());
    }
  }
}

// S8 in closed form: the discrete steady state for a constant force bias matches the continuous
// p~ = -b/d, v~ = -a b/d of the per-axis error dynamics.
TEST(NpoDesign, BiasResponseMatchesContinuousSteadyState) {
  const double w = 2.0 * std::numbers::pi * 50.0;
  for (const auto& [m, d, a] : std::array<std::array<double, 3>, 4>{
           {{kMass, 100.0, 1e4}, {1.799e-3, 100.0, 1e4}, {kMass, kMass * w * w, 1.4 * w}, {3.336e-3, 3.336e-3 * w * w, 1.4 * w}}}) {
    const npo::AxisDesign axis = npo::design_axis(m, d, a, kT, npo::Integrator::exact);
    const Eigen::Vector2d e = npo::bias_response(axis);
    EXPECT_NEAR(e(1) / (-a / d), 1.0, 1e-6) << "m " << m;
    EXPECT_NEAR(e(0) / (-1.0 / d), 1.0, 2e-3) << "m " << m;
  }
}

TEST(NpoDesign, ExactUpdateKeepsTheCompositeLyapunovFunctionNonIncreasing) {
  const double w = 2.0 * std::numbers::pi * 50.0;
  for (const auto& [m, d, a] : std::array<std::array<double, 3>, 3>{
           {{kMass, 100.0, 1e4}, {1.799e-3, 100.0, 1e4}, {kMass, kMass * w * w, 1.4 * w}}}) {
    const npo::AxisDesign axis = npo::design_axis(m, d, a, kT, npo::Integrator::exact);
    EXPECT_TRUE(npo::lyapunov_non_increasing(axis)) << "m " << m << " d " << d << " a " << a;
  }
}

// ---- the block ---------------------------------------------------------------------------------

struct LinearTruth {
  std::array<double, 6> p{}, v{};
  void advance(const std::array<double, 6>& f) {
    for (std::size_t i = 0; i < 6; ++i) {
      const double acc = f[i] / kM[i];
      p[i] += kT * v[i] + 0.5 * kT * kT * acc;
      v[i] += kT * acc;
    }
  }
};

std::unique_ptr<lode::testing::BlockHarness> make_observer(const std::string& params) {
  auto h = std::make_unique<lode::testing::BlockHarness>("estimator.npo", "model: stage\n" + params, kRateHz, kModels);
  h->feed("measurement", kPose);
  h->feed("force", kForce);
  return h;
}

void drive(lode::testing::BlockHarness& h, const LinearTruth& truth, const std::array<double, 6>& force) {
  auto z = h.input("measurement");
  auto f = h.input("force");
  for (std::size_t i = 0; i < 6; ++i) {
    z[i] = truth.p[i];
    f[i] = force[i];
  }
}

TEST(Npo, ReadsTheMassesOffTheProcessModel) {
  REQUIRE_PLANT();
  auto h = std::make_unique<lode::testing::BlockHarness>(
      "estimator.npo", "model: stage\nd0: 100\na0_per_s: 1e4\n", kRateHz,
      "stage: {plugin: plant.rigid_body6, mass_kg: 2.5, inertia_kg_m2: [1e-3, 2e-3, 3e-3], gravity_m_s2: 9.81}\n");
  h->feed("measurement", kPose);
  h->feed("force", kForce);
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  auto& block = dynamic_cast<lode::plugins::NonlinearPassiveObserver&>(h->block());
  const std::array<double, 6> expected{2.5, 2.5, 2.5, 1e-3, 2e-3, 3e-3};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(block.axis(i).mass, expected[i], 1e-12 * expected[i]) << i;
  const lode::Json described = h->describe();
  ASSERT_NE(described.find("axes"), nullptr);
  EXPECT_EQ(described.find("axes")->elements().size(), 6u);
  // Gravity along fixed -z is the model's force-free acceleration at rest (used by dynamics: linear).
  const auto& rest = described.find("force_free_acceleration_at_rest")->elements();
  ASSERT_EQ(rest.size(), 6u);
  EXPECT_NEAR(rest[2].as_number(), -9.81, 1e-12);
  for (std::size_t i : {0u, 1u, 3u, 4u, 5u}) EXPECT_EQ(rest[i].as_number(), 0.0) << i;
}

// With the true force and noise-free Z the estimate stays exact, whatever the gains:
// the innovations are zero from a matched start, so the update only runs the model.
TEST(Npo, PerfectModelFromAMatchedStartStaysExact) {
  REQUIRE_PLANT();
  for (const std::string integrator : {"exact", "backward_euler"}) {
    auto h = make_observer("dynamics: linear\nintegrator: " + integrator +
                           "\nd0: 100\na0_per_s: 1e4\ninitialize_from_first_measurement: false\n"
                           "initial_pose: [1e-6, 0, 0, 0, 0, 0]\ninitial_velocity: [1e-5, -2e-5, 5e-6, 1e-4, -3e-4, 2e-4]\n");
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
    LinearTruth truth;
    truth.p[0] = 1e-6;
    truth.v = {1e-5, -2e-5, 5e-6, 1e-4, -3e-4, 2e-4};
    double worst = 0.0, largest = 0.0;
    std::array<double, 6> held{};  // the force that moved the truth over the last period (readback)
    for (int k = 0; k < 2000; ++k) {
      drive(*h, truth, held);
      ASSERT_EQ(h->step(), lode::StepStatus::ok);
      for (std::size_t i = 0; i < 6; ++i) {
        worst = std::max(worst, std::abs(h->output("velocity")[i] - truth.v[i]));
        largest = std::max(largest, std::abs(truth.v[i]));
      }
      for (std::size_t i = 0; i < 6; ++i) held[i] = 1e-3 * kM[i] * std::sin(0.01 * k + static_cast<double>(i));
      truth.advance(held);
    }
    std::printf("%s from the true state: max |v^ - v| / max |v| = %.3g\n", integrator.c_str(), worst / largest);
    EXPECT_LT(worst / largest, 1e-9) << integrator;
  }
}

// Random initial errors decay with the designed poles: after n steps the error is E^n e0.
TEST(Npo, ErrorsDecayAsDesigned) {
  REQUIRE_PLANT();
  auto h = make_observer("dynamics: linear\nobserver_frequency_hz: 50\nobserver_damping: 0.7\n"
                         "initialize_from_first_measurement: false\n"
                         "initial_pose: [1e-6, -2e-6, 3e-7, 2e-6, -1e-6, 5e-6]\n"
                         "initial_velocity: [1e-4, 2e-4, -1e-4, 1e-3, 2e-3, -3e-3]\n");
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  ASSERT_TRUE(h->activate());
  auto& block = dynamic_cast<lode::plugins::NonlinearPassiveObserver&>(h->block());
  LinearTruth truth;  // at rest at the origin
  const std::array<double, 6> p0{1e-6, -2e-6, 3e-7, 2e-6, -1e-6, 5e-6};
  const std::array<double, 6> v0{1e-4, 2e-4, -1e-4, 1e-3, 2e-3, -3e-3};
  for (int k = 0; k <= 50; ++k) {
    drive(*h, truth, {});
    ASSERT_EQ(h->step(), lode::StepStatus::ok);
  }
  for (std::size_t i = 0; i < 6; ++i) {
    Eigen::Matrix2d e50 = Eigen::Matrix2d::Identity();
    for (int k = 0; k < 50; ++k) e50 = block.axis(i).transition * e50;
    const Eigen::Vector2d expected = e50 * Eigen::Vector2d(-p0[i], -v0[i]);  // e = truth - estimate
    EXPECT_NEAR(-h->output("velocity")[i], expected(1), 1e-9 * std::abs(v0[i])) << i;
    EXPECT_NEAR(-h->output("pose")[i], expected(0), 1e-9 * std::abs(p0[i]) + 1e-20) << i;
  }
}

// S8 through the block: a constant force bias b leaves v~ = a b / d.
TEST(Npo, ForceBiasLeavesVelocityErrorAbOverD) {
  REQUIRE_PLANT();
  auto h = make_observer("dynamics: linear\nobserver_frequency_hz: 50\nobserver_damping: 0.7\n");
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  ASSERT_TRUE(h->activate());
  auto& block = dynamic_cast<lode::plugins::NonlinearPassiveObserver&>(h->block());
  const std::array<double, 6> bias{1e-3, -2e-3, 5e-4, 1e-6, -2e-6, 3e-6};
  LinearTruth truth;
  for (int k = 0; k < 2500; ++k) {  // 1 s, 220 time constants of the 50 Hz, 0.7 design
    drive(*h, truth, bias);          // the observer is told F + b while the stage feels F = 0
    ASSERT_EQ(h->step(), lode::StepStatus::ok);
  }
  for (std::size_t i = 0; i < 6; ++i) {
    const double expected = block.axis(i).a * bias[i] / block.axis(i).d;  // v^ = v + a b / d
    EXPECT_NEAR(h->output("velocity")[i], expected, 1e-6 * std::abs(expected)) << i;
  }
}

TEST(Npo, FiniteDifferenceBaselineIsTheBackwardDifferenceOfZ) {
  REQUIRE_PLANT();
  auto h = make_observer("d0: 100\na0_per_s: 1e4\n");
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  ASSERT_TRUE(h->activate());
  ASSERT_EQ(h->output_elements("fd_velocity")[0].name, "x_dot");
  ASSERT_EQ(h->output_elements("fd_velocity")[0].unit, "m/s");
  ASSERT_EQ(h->output_elements("velocity")[3].name, "p");
  ASSERT_EQ(h->output_elements("velocity")[3].unit, "rad/s");
  auto z = h.get()->input("measurement");
  z[0] = 1e-6;
  z[4] = 2e-6;
  ASSERT_EQ(h->step(), lode::StepStatus::ok);
  EXPECT_EQ(h->output("fd_velocity")[0], 0.0);  // no previous sample on the first cycle
  z[0] = 1.5e-6;
  z[4] = 1e-6;
  ASSERT_EQ(h->step(), lode::StepStatus::ok);
  EXPECT_NEAR(h->output("fd_velocity")[0], 0.5e-6 / kT, 1e-15);
  EXPECT_NEAR(h->output("fd_velocity")[4], -1e-6 / kT, 1e-15);
  // The 12-element state is [pose, velocity], laid out like the plant's state.
  ASSERT_EQ(h->output_elements("state").size(), 12u);
  EXPECT_EQ(h->output_elements("state")[6].name, "u");
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(h->output("state")[i], h->output("pose")[i]);
    EXPECT_EQ(h->output("state")[6 + i], h->output("velocity")[i]);
  }
}

TEST(Npo, TuningRulePlacesTheErrorPoles) {
  REQUIRE_PLANT();
  auto h = make_observer("observer_frequency_hz: [50, 50, 50, 80, 80, 80]\nobserver_damping: 0.7\n");
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  auto& block = dynamic_cast<lode::plugins::NonlinearPassiveObserver&>(h->block());
  for (std::size_t i = 0; i < 6; ++i) {
    const double w = 2.0 * std::numbers::pi * (i < 3 ? 50.0 : 80.0);
    EXPECT_NEAR(block.axis(i).a, 1.4 * w, 1e-9);
    EXPECT_NEAR(block.axis(i).d, kM[i] * w * w, 1e-9 * kM[i] * w * w);
    EXPECT_NEAR(std::abs(block.axis(i).continuous_poles[0]), w, 1e-9 * w);
    EXPECT_NEAR(-block.axis(i).continuous_poles[0].real() / w, 0.7, 1e-12);
  }
  // Worked example: w = 2 pi 50, zeta 0.7, m = 0.931 -> a ~ 440 1/s, d ~ 9.2e4 N/m.
  EXPECT_NEAR(block.axis(0).a, 440.0, 0.5);
  EXPECT_NEAR(block.axis(0).d, 9.19e4, 100.0);
}

TEST(Npo, ForwardEulerAtTable2GainsIsRefusedWithItsEigenvalue) {
  REQUIRE_PLANT();
  auto h = make_observer("integrator: forward_euler\nd0: 100\na0_per_s: 1e4\n");
  EXPECT_FALSE(h->configure());
  const std::string d = h->diagnostics();
  EXPECT_NE(d.find("forward_euler is unstable"), std::string::npos) << d;
  EXPECT_NE(d.find("a0 T = 4"), std::string::npos) << d;
  EXPECT_NE(d.find("-3"), std::string::npos) << d;
  // Small gains are fine for forward Euler too.
  auto ok = make_observer("integrator: forward_euler\nobserver_frequency_hz: 20\nobserver_damping: 0.7\n");
  EXPECT_TRUE(ok->configure()) << ok->diagnostics();
}

TEST(Npo, ConfigurationErrorsAreReported) {
  REQUIRE_PLANT();
  {
    auto h = make_observer("");
    EXPECT_FALSE(h->configure());
    EXPECT_NE(h->diagnostics().find("no observer gains"), std::string::npos) << h->diagnostics();
  }
  {
    auto h = make_observer("d0: 100\na0_per_s: 1e4\nobserver_frequency_hz: 50\nobserver_damping: 0.7\n");
    EXPECT_FALSE(h->configure());
    EXPECT_NE(h->diagnostics().find("not both"), std::string::npos) << h->diagnostics();
  }
  {
    auto h = make_observer("d0: [100, 100, -1, 100, 100, 100]\na0_per_s: [1, 2]\n");
    EXPECT_FALSE(h->configure());
    EXPECT_NE(h->diagnostics().find("passivity"), std::string::npos) << h->diagnostics();
    EXPECT_NE(h->diagnostics().find("expected one number or 6"), std::string::npos) << h->diagnostics();
  }
  {
    auto h = std::make_unique<lode::testing::BlockHarness>("estimator.npo", "model: stage\nd0: 100\na0_per_s: 1\n",
                                                            kRateHz, kModels);
    h->feed("measurement", {{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}});
    h->feed("force", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});
    EXPECT_FALSE(h->configure());
    EXPECT_NE(h->diagnostics().find("6-DOF pose"), std::string::npos) << h->diagnostics();
    EXPECT_NE(h->diagnostics().find("no element 'fz'"), std::string::npos) << h->diagnostics();
  }
  {
    auto h = std::make_unique<lode::testing::BlockHarness>("estimator.npo", "model: nowhere\nd0: 100\na0_per_s: 1\n",
                                                            kRateHz, kModels);
    h->feed("measurement", kPose);
    h->feed("force", kForce);
    EXPECT_FALSE(h->configure());
    EXPECT_NE(h->diagnostics().find("nowhere"), std::string::npos) << h->diagnostics();
  }
}

// The force port may carry more than the force (e.g. io.sim's truth: pose and readback).
TEST(Npo, PicksTheForceOutOfAWiderPortByName) {
  REQUIRE_PLANT();
  auto h = std::make_unique<lode::testing::BlockHarness>("estimator.npo",
                                                          "model: stage\ndynamics: linear\nd0: 100\na0_per_s: 1e4\n",
                                                          kRateHz, kModels);
  lode::Elements wide = kPose;
  wide.insert(wide.end(), kForce.rbegin(), kForce.rend());  // reversed order on purpose
  h->feed("measurement", kPose);
  h->feed("force", wide);
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  ASSERT_TRUE(h->activate());
  auto f = h->input("force");
  ASSERT_EQ(h->step(), lode::StepStatus::ok);
  f[6 + 5] = kMass;  // fx: 1 m/s^2
  ASSERT_EQ(h->step(), lode::StepStatus::ok);
  // One period of 1 m/s^2 from rest while Z has not moved: v^- = T, nu^- = -T^2/2, so
  // v^ = T - h_v T^2 / 2; nothing on the other axes.
  const double h_v = dynamic_cast<lode::plugins::NonlinearPassiveObserver&>(h->block()).axis(0).h_v;
  EXPECT_NEAR(h->output("velocity")[0], kT - h_v * kT * kT / 2.0, 1e-15);
  for (std::size_t i = 1; i < 6; ++i) EXPECT_EQ(h->output("velocity")[i], 0.0) << i;
}

TEST(Npo, NonFiniteInputsFault) {
  REQUIRE_PLANT();
  auto h = make_observer("d0: 100\na0_per_s: 1e4\n");
  ASSERT_TRUE(h->configure()) << h->diagnostics();
  ASSERT_TRUE(h->activate());
  h->input("force")[2] = std::nan("");
  EXPECT_EQ(h->step(), lode::StepStatus::fault);
  EXPECT_STREQ(h->block().fault_reason(), "non-finite force");
}

TEST(Npo, NoAllocationInStep) {
  REQUIRE_PLANT();
  LODE_REQUIRE_ALLOCATION_COUNTING();
  for (const std::string dynamics : {"nonlinear", "linear"}) {
    auto h = make_observer("dynamics: " + dynamics + "\nd0: 100\na0_per_s: 1e4\n");
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
    auto z = h->input("measurement");
    auto f = h->input("force");
    const std::size_t before = lode::testing::allocation_count();
    for (int k = 0; k < 10000; ++k) {
      for (std::size_t i = 0; i < 6; ++i) {
        z[i] = 1e-6 * std::sin(0.001 * k + static_cast<double>(i));
        f[i] = 1e-3 * std::cos(0.001 * k);
      }
      if (h->step() != lode::StepStatus::ok) FAIL() << h->block().fault_reason();
    }
    EXPECT_EQ(lode::testing::allocation_count() - before, 0u) << dynamics;
  }
}

}  // namespace
