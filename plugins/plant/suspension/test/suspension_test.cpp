// plant.suspension: the force-fit constants (Table 3 -> Table 4), the stage-1 NNLS fit, why the
// printed model (eq. 32) cannot be simulated, the coil and free-fall closed forms, the end stops,
// the Euler process model (eq. 33) and its Jacobian, and the YAML path.
#include "suspension.hpp"

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

using lode::plugins::Suspension;
using lode::plugins::SuspensionConfig;
using lode::plugins::SuspensionDiscretization;
using lode::plugins::plants::testing::configure_refused_naming;
using lode::plugins::plants::testing::element_list;
using lode::plugins::plants::testing::state_of;

constexpr double kDt = 0.5e-3;  // t_s of the paper


// Table 3 of the paper: per-current fits of F_1e = a d^-4 + b d^-2.
const std::vector<double> kCurrents{0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4};
const std::vector<double> kTableA{5.999e-9, 5.98e-9, 6.012e-9, 6.005e-9, 5.985e-9, 5.994e-9, 5.989e-9, 6.007e-9};
const std::vector<double> kTableB{7.587e-8,  88.6e-8,  174.4e-8, 263.4e-8,
                                  357.1e-8, 450.6e-8, 543.1e-8, 637.2e-8};

TEST(SuspensionForceFit, StageTwoReproducesTable4) {
  // Criteria: a-bar within 0.1 %, m within 0.5 %, J_3 within 10 % of Table 4.
  const auto fit = lode::plugins::fit_force_coefficients(kCurrents, kTableA, kTableB);
  ASSERT_TRUE(fit) << fit.error();
  std::printf("stage-2 fit: a = %.5e (Table 4 5.996e-9), m = %.5e (4.509e-6), J_3 = %.4e (2.0486e-14)\n",
              fit.value().a_mean, fit.value().b_per_current, fit.value().j3);
  EXPECT_NEAR(fit.value().a_mean, 5.996e-9, 5.996e-9 * 1e-3);
  EXPECT_NEAR(fit.value().b_per_current, 4.509e-6, 4.509e-6 * 5e-3);
  EXPECT_NEAR(fit.value().j3, 2.0486e-14, 2.0486e-14 * 0.10);
}

TEST(SuspensionForceFit, RejectsMismatchedTables) {
  EXPECT_FALSE(lode::plugins::fit_force_coefficients({0.0, 1.0}, {1e-9}, {1e-8, 2e-8}));
  EXPECT_FALSE(lode::plugins::fit_force_coefficients({0.0, 0.0}, {1e-9, 1e-9}, {1e-8, 2e-8}));
}

std::vector<double> fem_grid() {  // 15 ... 45 mm in 0.5 mm steps: the FEM sweep (61 points)
  std::vector<double> d;
  for (int k = 0; k <= 60; ++k) d.push_back(0.015 + 0.0005 * k);
  return d;
}

TEST(SuspensionForceFit, StageOneRecoversTheForceLawAndPrefersIt) {
  // On forces that follow eq. 13 exactly, F_1e recovers (a, b) and its residual stays flat
  // across currents, while the one-term F_2e's grows with the current (Table 3, Fig. 8-9).
  const std::vector<double> d = fem_grid();
  double previous_j2 = -1.0;
  for (double i : kCurrents) {
    std::vector<double> f;
    for (double x : d) f.push_back(5.996e-9 / std::pow(x, 4) + 4.509e-6 * i / (x * x));
    const auto one = lode::plugins::fit_force_curve(d, f);
    const auto two = lode::plugins::fit_force_curve_d4(d, f);
    ASSERT_TRUE(one && two);
    EXPECT_NEAR(one.value().a, 5.996e-9, 5.996e-9 * 1e-9) << i;
    EXPECT_NEAR(one.value().b, 4.509e-6 * i, 1e-15) << i;
    EXPECT_LT(one.value().cost, 1e-20) << i;
    if (i > 0) {
      EXPECT_GT(two.value().cost, previous_j2) << "J_2 grows with the current";
    }
    previous_j2 = two.value().cost;
  }
}

TEST(SuspensionForceFit, StageOneIsNonNegative) {
  // A curve that least squares would fit with b < 0: the NNLS keeps b = 0 (only positive
  // solutions were allowed, eq. 10).
  const std::vector<double> d = fem_grid();
  std::vector<double> f;
  for (double x : d) f.push_back(6e-9 / std::pow(x, 4) - 2e-6 / (x * x));
  const auto fit = lode::plugins::fit_force_curve(d, f);
  ASSERT_TRUE(fit);
  EXPECT_EQ(fit.value().b, 0.0);
  EXPECT_GT(fit.value().a, 0.0);
  EXPECT_FALSE(lode::plugins::fit_force_curve({0.02}, {1.0}));
  EXPECT_FALSE(lode::plugins::fit_force_curve({0.02, -0.01}, {1.0, 2.0}));
}

SuspensionConfig paper_config() { return SuspensionConfig{}; }

SuspensionConfig pipeline_config() {  // config/suspension_ukf.yaml: the self-consistent plant
  SuspensionConfig c;
  c.mass_kg = 6.0e-3;
  c.force_b_n_m2_per_a = 4.85e-5;
  return c;
}

TEST(SuspensionPhysics, PrintedModelCannotHoldTheMagnetInsideTheClamp) {
  // With the mass, the zero-current balance is ~19.4 mm, and holding 22-30 mm
  // needs 1.8-7 A, far beyond the 0.19-1.12 A that the PID's 0.5-3 V clamp allows.
  Suspension s;
  s.apply(paper_config());
  EXPECT_NEAR(s.zero_current_gap_m(), 0.01936, 0.0001);
  EXPECT_NEAR(s.hold_current_a(0.022), 1.83, 0.02);
  EXPECT_NEAR(s.hold_current_a(0.030), 7.04, 0.05);
  EXPECT_GT(s.hold_voltage_v(0.022), 3.0);
  // At 20 mm the magnet alone pulls 0.0375 N against a weight of 0.0427 N.
  EXPECT_NEAR(s.force_n(0.020, 0.0), 0.0375, 0.0001);
}

TEST(SuspensionPhysics, PipelinePlantHoldsTwentyTwoToThirtyMillimetresInsideTheClamp) {
  Suspension s;
  s.apply(pipeline_config());
  for (double d = 0.022; d <= 0.0300001; d += 0.001) {
    EXPECT_GT(s.hold_voltage_v(d), 0.5 * 1.25) << d;  // 25 % margin to the clamp at both ends
    EXPECT_LT(s.hold_voltage_v(d), 3.0 / 1.15) << d;
    EXPECT_GT(s.unstable_pole_rad_s(d), 25.0);
    EXPECT_LT(s.unstable_pole_rad_s(d), 40.0);
  }
  // The room the clamp leaves (README): the steady current at 0.5 V already lifts the magnet
  // above 20.1 mm, the one at 3 V no longer holds it below 31.9 mm.
  const double weight = 6.0e-3 * 9.81;
  const double i_min = 0.5 * 61.61 / 165.6;
  const double i_max = 3.0 * 61.61 / 165.6;
  EXPECT_GT(s.force_n(0.0200, i_min), weight);
  EXPECT_LT(s.force_n(0.0202, i_min), weight);
  EXPECT_GT(s.force_n(0.0318, i_max), weight);
  EXPECT_LT(s.force_n(0.0320, i_max), weight);
  // At rest at the hold current the acceleration vanishes.
  const double d = 0.025;
  const std::array<double, 3> x{d, 0.0, s.hold_current_a(d)};
  std::array<double, 3> dx{};
  s.derivative(x.data(), s.hold_voltage_v(d), dx.data());
  EXPECT_NEAR(dx[1], 0.0, 1e-12);
  EXPECT_NEAR(dx[2], 0.0, 1e-12);
}

TEST(SuspensionPhysics, CoilConstantsImpliedByEq32) {
  Suspension s;
  lode::Json out = lode::Json::object();
  s.describe(out);
  EXPECT_NEAR(out.find("coil_inductance_h")->as_number(), 16.23e-3, 0.01e-3);
  EXPECT_NEAR(out.find("coil_resistance_ohm")->as_number(), 2.688, 0.001);
  EXPECT_NEAR(out.find("coil_time_constant_s")->as_number(), 6.04e-3, 0.01e-3);
  EXPECT_NEAR(out.find("coil_static_gain_a_per_v")->as_number(), 0.372, 0.001);
}

/// Advances `s` with `u` held for steps k = 1 ... steps; check(k, t_k, state) after each.
template <typename Check>
void advance_held(Suspension& s, double u, int steps, const Check& check) {
  for (int k = 1; k <= steps; ++k) {
    s.advance(kDt, &u);
    check(k, k * kDt, state_of(s));
  }
}

TEST(SuspensionPhysics, CoilCurrentFollowsTheFirstOrderClosedForm) {
  SuspensionConfig c = pipeline_config();
  c.initial_current_a = 0.0;
  c.force_a_n_m4 = 0.0;
  c.gravity_m_s2 = 0.0;  // keep the magnet where it is: only the coil moves
  c.force_b_n_m2_per_a = 1e-30;
  Suspension s;
  s.apply(c);
  const double u = 2.0;
  advance_held(s, u, 40, [&](int k, double t, const Suspension::State& x) {
    const double exact = 61.61 / 165.6 * u * (1.0 - std::exp(-165.6 * t));
    EXPECT_NEAR(x[2], exact, 1e-9 * exact) << k;
  });
  std::array<double, 2> y{};
  s.output(y.data());
  EXPECT_EQ(y[1], u);  // the held voltage is read back
}

TEST(SuspensionPhysics, FreeFallIsExact) {
  // Without magnetic force the body falls as d0 + g t^2 / 2 (RK4 is exact for it).
  SuspensionConfig c = pipeline_config();
  c.force_a_n_m4 = 0.0;
  c.initial_current_a = 0.0;
  Suspension s;
  s.apply(c);
  advance_held(s, 0.0, 100, [](int k, double t, const Suspension::State& x) {
    EXPECT_NEAR(x[0], 0.026 + 0.5 * 9.81 * t * t, 1e-15) << k;
    EXPECT_NEAR(x[1], 9.81 * t, 1e-13) << k;
  });
  EXPECT_EQ(s.stop_contacts(), 0u);
}

TEST(SuspensionPhysics, EndStopsCatchTheMagnet) {
  Suspension s;
  s.apply(pipeline_config());
  const double off = 0.0;  // coil off: the magnet falls to the floor
  for (int k = 0; k < 2000; ++k) s.advance(kDt, &off);
  auto x = state_of(s);
  EXPECT_EQ(x[0], 0.050);
  EXPECT_EQ(x[1], 0.0);
  EXPECT_GT(s.stop_contacts(), 0u);
  s.reset();
  EXPECT_EQ(s.stop_contacts(), 0u);
  const double full = 3.0;  // full attraction: it snaps to the coil face
  for (int k = 0; k < 2000; ++k) s.advance(kDt, &full);
  x = state_of(s);
  EXPECT_EQ(x[0], 0.012);
  EXPECT_TRUE(std::isfinite(x[1]) && std::isfinite(x[2]));
}

TEST(SuspensionProcess, EulerStepIsEq33) {
  Suspension s;
  s.apply(pipeline_config());
  const std::array<double, 3> x{0.024, 0.01, 0.5};
  const double u = 1.2;
  std::array<double, 3> next{};
  s.propagate(kDt, x.data(), &u, next.data());
  const SuspensionConfig c = pipeline_config();
  const double acc = 9.81 - (c.force_a_n_m4 / std::pow(0.024, 4) + c.force_b_n_m2_per_a * 0.5 / (0.024 * 0.024)) / c.mass_kg;
  EXPECT_DOUBLE_EQ(next[0], 0.024 + 0.01 * kDt);
  EXPECT_NEAR(next[1], 0.01 + acc * kDt, 1e-15);
  EXPECT_NEAR(next[2], 0.5 + (-165.6 * 0.5 + 61.61 * 1.2) * kDt, 1e-15);
}

TEST(SuspensionProcess, AnalyticJacobianMatchesCentralDifferences) {
  Suspension s;
  s.apply(pipeline_config());
  double worst = 0.0;
  for (double d : {0.020, 0.025, 0.030}) {
    for (double i : {0.2, 0.9}) {
      const std::array<double, 3> x{d, -0.02, i};
      const double u = 1.0;
      std::array<double, 9> F{};
      ASSERT_TRUE(s.process_jacobian(kDt, x.data(), &u, F.data()));
      for (std::size_t j = 0; j < 3; ++j) {
        const double h = 1e-6 * std::max(std::abs(x[j]), 1e-3);
        std::array<double, 3> plus = x, minus = x, fp{}, fm{};
        plus[j] += h;
        minus[j] -= h;
        s.propagate(kDt, plus.data(), &u, fp.data());
        s.propagate(kDt, minus.data(), &u, fm.data());
        for (std::size_t r = 0; r < 3; ++r) {
          const double numeric = (fp[r] - fm[r]) / (2 * h);
          worst = std::max(worst, std::abs(F[r * 3 + j] - numeric) / std::max(std::abs(numeric), 1e-9));
        }
      }
    }
  }
  EXPECT_LT(worst, 1e-6);
  // The coil pole of eq. 33: 1 - 165.6 t_s = 0.9172.
  std::array<double, 9> F{};
  const std::array<double, 3> x{0.025, 0.0, 0.5};
  const double u = 0.0;
  s.process_jacobian(kDt, x.data(), &u, F.data());
  EXPECT_NEAR(F[8], 0.9172, 1e-12);
}

TEST(SuspensionProcess, Rk4DiscretisationHasNoAnalyticJacobian) {
  SuspensionConfig c = pipeline_config();
  c.process_discretization = SuspensionDiscretization::rk4;
  c.substeps = 1;
  Suspension s;
  s.apply(c);
  const std::array<double, 3> x{0.026, 0.0, s.hold_current_a(0.026) + 0.05};
  const double u = 1.5;
  std::array<double, 9> F{};
  EXPECT_FALSE(s.process_jacobian(kDt, x.data(), &u, F.data()));
  // One RK4 step equals the simulator's advance with one substep.
  std::array<double, 3> next{};
  s.propagate(kDt, x.data(), &u, next.data());
  SuspensionConfig start = c;
  start.initial_current_a = x[2];
  Suspension sim;
  sim.apply(start);
  sim.advance(kDt, &u);
  std::array<double, 3> y{};
  sim.state(y.data());
  for (std::size_t i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(next[i], y[i]);
}

TEST(SuspensionProcess, PointsInOneCallAreEachPropagatedAsAlone) {
  // propagate_points() (a UKF's 2n + 1 sigma points in one call) must give every point the
  // bits propagate() gives it alone: the filters' estimates are compared bit for bit. Points
  // far apart (one on the coil face, where the force is held), both discretisations.
  for (const auto discretization : {SuspensionDiscretization::euler, SuspensionDiscretization::rk4}) {
    SuspensionConfig c = pipeline_config();
    c.process_discretization = discretization;
    Suspension s;
    s.apply(c);
    const std::array<std::array<double, 3>, 7> points{{{0.026, 0.0, 0.6375},
                                                       {0.0261, 0.001, 0.64},
                                                       {0.0259, -0.002, 0.63},
                                                       {0.024, 0.01, 0.5},
                                                       {0.030, -0.01, 0.9},
                                                       {0.0005, 0.0, 0.2},
                                                       {0.026, 0.0, 0.6376}}};
    const double u = 1.2;
    std::array<double, 21> batch{};
    s.propagate_points(kDt, points[0].data(), points.size(), &u, batch.data());
    for (std::size_t i = 0; i < points.size(); ++i) {
      std::array<double, 3> alone{};
      s.propagate(kDt, points[i].data(), &u, alone.data());
      for (std::size_t j = 0; j < 3; ++j)
        EXPECT_EQ(batch[3 * i + j], alone[j]) << "point " << i << " element " << j << ", "
                                              << (discretization == SuspensionDiscretization::rk4 ? "rk4" : "euler");
    }
  }
}

TEST(SuspensionPlant, ElementsAndReset) {
  Suspension s;
  s.apply(pipeline_config());
  EXPECT_EQ(element_list(s.inputs()), "coil_voltage [V]");
  EXPECT_EQ(element_list(s.outputs()), "gap [m], coil_voltage [V]");
  EXPECT_EQ(element_list(s.state_elements()), "gap [m], velocity [m/s], current [A]");
  // The estimator's f runs on the simulator's state and inputs.
  EXPECT_EQ(element_list(s.process_state()), element_list(s.state_elements()));
  EXPECT_EQ(element_list(s.process_inputs()), element_list(s.inputs()));
  // Starts at rest with the hold current, and the voltage that holds it read back.
  std::array<double, 2> y{};
  s.output(y.data());
  EXPECT_EQ(y[0], 0.026);
  EXPECT_NEAR(y[1], s.hold_voltage_v(0.026), 1e-15);
  const double u = 0.7;
  s.advance(kDt, &u);
  s.reset();
  const auto x = state_of(s);
  EXPECT_EQ(x[0], 0.026);
  EXPECT_EQ(x[1], 0.0);
  EXPECT_NEAR(x[2], s.hold_current_a(0.026), 1e-15);
}

// The YAML path, through io.sim (the block that owns a plant in a pipeline).
TEST(SuspensionYaml, ForceFitTableGivesTable4) {
  LODE_REQUIRE_PLUGINS("sensor.hall_gap", "io.sim");
  lode::testing::BlockHarness h(
      "io.sim", "plant: plant\nsensors: hall\n", 2000.0,
      "plant:\n  plugin: plant.suspension\n  force_fit:\n    current_a: [0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4]\n"
      "    a_n_m4: [5.999e-9, 5.98e-9, 6.012e-9, 6.005e-9, 5.985e-9, 5.994e-9, 5.989e-9, 6.007e-9]\n"
      "    b_n_m2: [7.587e-8, 88.6e-8, 174.4e-8, 263.4e-8, 357.1e-8, 450.6e-8, 543.1e-8, 637.2e-8]\n"
      "hall: {plugin: sensor.hall_gap}\n");
  h.feed("command", {{"coil_voltage", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const lode::Json d = h.describe();
  const lode::Json* plant = d.find("plant_model");
  ASSERT_NE(plant, nullptr) << d.dump();
  EXPECT_NEAR(plant->find("force_a_n_m4")->as_number(), 5.996e-9, 5.996e-12);
  EXPECT_NEAR(plant->find("force_b_n_m2_per_a")->as_number(), 4.509e-6, 4.509e-6 * 5e-3);
  const lode::Json* fit = plant->find("force_fit");
  ASSERT_NE(fit, nullptr);
  EXPECT_NEAR(fit->find("j3")->as_number(), 2.0486e-14, 0.2e-14);
}

TEST(SuspensionYaml, InvalidValuesAreLocatedErrors) {
  LODE_REQUIRE_PLUGINS("sensor.hall_gap", "io.sim");
  lode::testing::BlockHarness h(
      "io.sim", "plant: plant\nsensors: hall\n", 2000.0,
      "plant: {plugin: plant.suspension, mass_kg: -1, gap_limits_m: [0.03, 0.02], initial_gap_m: 0.06, "
      "substeps: 0, process_discretization: midpoint, force_b_n_m2_per_a: 0}\n"
      "hall: {plugin: sensor.hall_gap}\n");
  h.feed("command", {{"coil_voltage", "V"}});
  EXPECT_TRUE(configure_refused_naming(
      h, {"models.plant.mass_kg: must be > 0 kg, got -1", "models.plant.gap_limits_m: expected",
          "models.plant.initial_gap_m: must lie within", "models.plant.substeps",
          "models.plant.process_discretization", "models.plant.force_b_n_m2_per_a"}));
}

}  // namespace
