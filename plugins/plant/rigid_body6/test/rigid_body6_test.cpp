// plant.rigid_body6: Eq. 9-10 of Gutierrez & Li (2024) checked against closed forms and
// conservation laws that only hold when the Coriolis/gyroscopic signs, R_BF and E agree:
// a force-free body keeps its fixed-frame momentum, a torque-free one its fixed-frame angular
// momentum and energy; E turns body rates into the rates of R_BF; the process model is the
// simulator bit for bit; parameters reach the physics through YAML.
#include "rigid_body6.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/require.hpp"
#include "plant_testing.hpp"

namespace {

using lode::plugins::RigidBody6;
using lode::plugins::RigidBody6Config;
using lode::plugins::plants::testing::configure_refused_naming;
using lode::plugins::plants::testing::element_list;
using lode::plugins::plants::testing::state_of;
namespace rb = lode::plugins::rigid_body6;

constexpr double kDt = 4e-4;  // the paper's 2.5 kHz loop

std::array<double, 3> fixed_frame(const rb::State& x, std::size_t first) {
  const rb::Matrix3 r = rb::rotation_body_to_fixed(x[rb::kPhi], x[rb::kTheta], x[rb::kPsi]);
  std::array<double, 3> out{};
  for (std::size_t i = 0; i < 3; ++i) {
    out[i] = r[i][0] * x[first] + r[i][1] * x[first + 1] + r[i][2] * x[first + 2];
  }
  return out;
}

TEST(RigidBody6, DeclaresPortsWithSiUnitsAndTable1Defaults) {
  RigidBody6 body;
  const std::string pose = "x [m], y [m], z [m], phi [rad], theta [rad], psi [rad]";
  const std::string wrench = "fx [N], fy [N], fz [N], tx [N*m], ty [N*m], tz [N*m]";
  EXPECT_EQ(element_list(body.inputs()), wrench);
  EXPECT_EQ(element_list(body.outputs()), pose + ", " + wrench);  // the pose, then the applied force read back
  EXPECT_EQ(element_list(body.state_elements()),
            pose + ", u [m/s], v [m/s], w [m/s], p [rad/s], q [rad/s], r [rad/s]");
  // The process model has the same layout.
  EXPECT_EQ(body.process_state().size(), 12u);
  EXPECT_EQ(body.process_inputs().size(), 6u);
  // Table 1 of Gutierrez & Li 2024.
  EXPECT_EQ(body.config().physics.mass_kg, 0.931);
  EXPECT_EQ(body.config().physics.inertia_kg_m2[0], 1.799e-3);
  EXPECT_EQ(body.config().physics.inertia_kg_m2[1], 1.834e-3);
  EXPECT_EQ(body.config().physics.inertia_kg_m2[2], 3.336e-3);
}

TEST(RigidBody6, RotationIsOrthonormalAndZyxComposed) {
  const double phi = 0.3, theta = -0.4, psi = 1.1;
  const rb::Matrix3 r = rb::rotation_body_to_fixed(phi, theta, psi);
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = 0; j < 3; ++j) {
      double dot = 0.0;
      for (std::size_t k = 0; k < 3; ++k) dot += r[k][i] * r[k][j];
      EXPECT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-15);
    }
  }
  // Pure yaw turns the body x axis towards fixed +y; pure pitch tips it towards -z.
  const rb::Matrix3 yaw = rb::rotation_body_to_fixed(0.0, 0.0, 0.5);
  EXPECT_NEAR(yaw[1][0], std::sin(0.5), 1e-16);
  const rb::Matrix3 pitch = rb::rotation_body_to_fixed(0.0, 0.5, 0.0);
  EXPECT_NEAR(pitch[2][0], -std::sin(0.5), 1e-16);
  const rb::Matrix3 roll = rb::rotation_body_to_fixed(0.5, 0.0, 0.0);
  EXPECT_NEAR(roll[2][1], std::sin(0.5), 1e-16);  // body y tips towards +z
}

// E maps body rates to Euler-angle rates: R(Theta + E Omega dt) ~ R(Theta) (I + [Omega]x dt).
TEST(RigidBody6, EulerRateMatrixMatchesTheRotationKinematics) {
  const double phi = 0.3, theta = -0.4, psi = 1.1;
  const std::array<double, 3> omega{0.7, -0.2, 0.5};
  const rb::Matrix3 e = rb::euler_rate_matrix(phi, theta);
  std::array<double, 3> rates{};
  for (std::size_t i = 0; i < 3; ++i) rates[i] = e[i][0] * omega[0] + e[i][1] * omega[1] + e[i][2] * omega[2];
  const double h = 1e-6;
  const rb::Matrix3 plus = rb::rotation_body_to_fixed(phi + h * rates[0], theta + h * rates[1], psi + h * rates[2]);
  const rb::Matrix3 minus = rb::rotation_body_to_fixed(phi - h * rates[0], theta - h * rates[1], psi - h * rates[2]);
  const rb::Matrix3 r = rb::rotation_body_to_fixed(phi, theta, psi);
  const double skew[3][3] = {{0, -omega[2], omega[1]}, {omega[2], 0, -omega[0]}, {-omega[1], omega[0], 0}};
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = 0; j < 3; ++j) {
      const double numeric = (plus[i][j] - minus[i][j]) / (2.0 * h);
      double expected = 0.0;
      for (std::size_t k = 0; k < 3; ++k) expected += r[i][k] * skew[k][j];
      EXPECT_NEAR(numeric, expected, 1e-9) << i << "," << j;
    }
  }
}

// Constant force, no rotation: RK4 integrates the quadratic exactly.
TEST(RigidBody6, ConstantForceMatchesClosedForm) {
  RigidBody6 body;
  const double u[6] = {0.0931, -0.1862, 0.04655, 0.0, 0.0, 0.0};  // 0.1, -0.2, 0.05 m/s^2
  for (int k = 0; k < 250; ++k) body.advance(kDt, u);
  const double t = 250 * kDt;
  const rb::State x = state_of(body);
  const double a[3] = {0.1, -0.2, 0.05};
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(x[rb::kX + i], 0.5 * a[i] * t * t, 1e-15);
    EXPECT_NEAR(x[rb::kU + i], a[i] * t, 1e-15);
  }
  double y[12];
  body.output(y);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(y[6 + i], u[i]) << "readback of the held force";
}

// A force-free body that translates and spins: its body-frame velocity rotates (Coriolis term
// -Omega x v) but the fixed-frame velocity R_BF v must stay constant.
TEST(RigidBody6, ForceFreeBodyKeepsFixedFrameMomentum) {
  RigidBody6Config c;
  c.initial = {0.0, 0.0, 0.0, 0.1, -0.2, 0.3};
  c.initial_velocity = {1e-3, -2e-3, 0.5e-3, 0.0, 0.0, 2.0};  // spin about the body z (a principal axis)
  RigidBody6 body;
  body.apply(c);
  const std::array<double, 3> v0 = fixed_frame(state_of(body), rb::kU);
  const double zero[6] = {};
  for (int k = 0; k < 2500; ++k) body.advance(kDt, zero);  // 1 s, the body turns by 2 rad
  const rb::State x = state_of(body);
  const std::array<double, 3> v1 = fixed_frame(x, rb::kU);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(v1[i], v0[i], 1e-12) << "fixed-frame velocity " << i;
    EXPECT_NEAR(x[rb::kX + i], v0[i] * 1.0, 1e-12) << "straight line " << i;
  }
  // The body-frame velocity did rotate.
  EXPECT_GT(std::abs(x[rb::kU] - c.initial_velocity[0]), 1e-4);
}

// Torque-free tumbling about no principal axis: energy and the fixed-frame angular momentum
// R_BF I Omega are conserved (checks Euler's equations, R_BF and E together).
TEST(RigidBody6, TorqueFreeTumblingConservesEnergyAndAngularMomentum) {
  RigidBody6Config c;
  c.initial = {0.0, 0.0, 0.0, 0.2, 0.1, -0.3};
  c.initial_velocity = {0.0, 0.0, 0.0, 1.0, 0.3, -0.5};
  c.substeps = 4;
  RigidBody6 body;
  body.apply(c);
  const auto& inertia = c.physics.inertia_kg_m2;
  auto momentum = [&](const rb::State& x) {
    rb::State s = x;
    for (std::size_t i = 0; i < 3; ++i) s[rb::kP + i] *= inertia[i];
    return fixed_frame(s, rb::kP);
  };
  auto energy = [&](const rb::State& x) {
    double e = 0.0;
    for (std::size_t i = 0; i < 3; ++i) e += 0.5 * inertia[i] * x[rb::kP + i] * x[rb::kP + i];
    return e;
  };
  const rb::State x0 = state_of(body);
  const auto h0 = momentum(x0);
  const double e0 = energy(x0);
  const double zero[6] = {};
  for (int k = 0; k < 2500; ++k) body.advance(kDt, zero);
  const rb::State x1 = state_of(body);
  const auto h1 = momentum(x1);
  const double h_norm = std::sqrt(h0[0] * h0[0] + h0[1] * h0[1] + h0[2] * h0[2]);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(h1[i], h0[i], 1e-9 * h_norm) << i;
  EXPECT_NEAR(energy(x1), e0, 1e-10 * e0);
  // It did tumble: the body rates changed by much more than the tolerance.
  EXPECT_GT(std::abs(x1[rb::kQ] - x0[rb::kQ]), 0.05);
}

// Gravity along -z of the fixed frame whatever the attitude (z up, assumed).
TEST(RigidBody6, GravityPullsAlongFixedMinusZAtAnyAttitude) {
  RigidBody6Config c;
  c.physics.gravity_m_s2 = 9.81;
  c.initial = {0.0, 0.0, 0.0, 0.3, -0.2, 0.7};
  RigidBody6 body;
  body.apply(c);
  const double zero[6] = {};
  for (int k = 0; k < 500; ++k) body.advance(kDt, zero);
  const double t = 500 * kDt;
  const rb::State x = state_of(body);
  const std::array<double, 3> v = fixed_frame(x, rb::kU);
  EXPECT_NEAR(v[0], 0.0, 1e-14);
  EXPECT_NEAR(v[1], 0.0, 1e-14);
  EXPECT_NEAR(v[2], -9.81 * t, 1e-13);
  EXPECT_NEAR(x[rb::kZ], -0.5 * 9.81 * t * t, 1e-13);
}

TEST(RigidBody6, ProcessModelIsTheSimulatorBitForBit) {
  RigidBody6Config c;
  c.initial = {1e-6, -2e-6, 3e-7, 4e-6, -1e-6, 2e-6};
  c.initial_velocity = {1e-5, 2e-5, -1e-5, 3e-3, -2e-3, 1e-3};
  c.substeps = 2;
  RigidBody6 body;
  body.apply(c);
  rb::State x = state_of(body);
  for (int k = 0; k < 100; ++k) {
    const double u[6] = {1e-3 * std::sin(0.1 * k), 2e-3, -1e-3, 1e-6, -2e-6 * std::cos(0.2 * k), 3e-6};
    rb::State predicted;
    body.propagate(kDt, x.data(), u, predicted.data());
    body.advance(kDt, u);
    x = state_of(body);
    for (std::size_t i = 0; i < rb::kStateSize; ++i) ASSERT_EQ(predicted[i], x[i]) << "cycle " << k << " state " << i;
  }
}

TEST(RigidBody6, ResetRestoresTheInitialConditionAndClearsTheReadback) {
  RigidBody6Config c;
  c.initial = {1e-3, 0, 0, 0, 0, 0};
  RigidBody6 body;
  body.apply(c);
  const double u[6] = {1, 1, 1, 1e-3, 1e-3, 1e-3};
  for (int k = 0; k < 10; ++k) body.advance(kDt, u);
  body.reset();
  const rb::State x = state_of(body);
  EXPECT_EQ(x[rb::kX], 1e-3);
  for (std::size_t i = 1; i < rb::kStateSize; ++i) EXPECT_EQ(x[i], 0.0);
  double y[12];
  body.output(y);
  for (std::size_t i = 6; i < 12; ++i) EXPECT_EQ(y[i], 0.0);
}


// The YAML path: io.sim owns a plant in a pipeline; its truth output reads the pose and the
// force readback, its plant_state the body velocities.
TEST(RigidBody6Yaml, ParametersReachThePhysics) {
  LODE_REQUIRE_PLUGINS("sensor.capacitive_gap");
  lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: gaps\nnoise_std_v: 0\nadc_bits: 0\n", 2500.0,
                                "stage: {plugin: plant.rigid_body6, mass_kg: 2.0, inertia_kg_m2: [1e-3, 2e-3, 4e-3],"
                                " initial: [1e-6, 0, 0, 0, 0, 0], substeps: 2}\n"
                                "gaps: {plugin: sensor.capacitive_gap}\n");
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto cmd = h.input("command");
  cmd[0] = 2.0;    // 1 m/s^2 on 2 kg
  cmd[5] = 4e-3;   // 1 rad/s^2 about z on Iz = 4e-3
  for (int k = 0; k < 10; ++k) {
    h.step();
    h.write();
  }
  h.step();  // sample after 10 periods
  const double t = 10 * kDt;
  EXPECT_NEAR(h.output("truth")[0], 1e-6 + 0.5 * t * t, 1e-15);
  EXPECT_NEAR(h.output("truth")[5], 0.5 * t * t, 1e-15);
  EXPECT_EQ(h.output("truth")[6], 2.0);  // readback
  // The spin about z turns the body axes under the fixed-frame motion: u = t - O(r^2 t^3) ~ 7e-14.
  EXPECT_NEAR(h.output("plant_state")[6], t, 1e-12);
  EXPECT_NEAR(h.output("plant_state")[11], t, 1e-15);
}

TEST(RigidBody6Yaml, InvalidPhysicsIsReportedAtOnce) {
  LODE_REQUIRE_PLUGINS("sensor.capacitive_gap");
  lode::testing::BlockHarness h("io.sim", "plant: stage\nsensors: gaps\n", 2500.0,
                                "stage: {plugin: plant.rigid_body6, mass_kg: -1, inertia_kg_m2: [1e-3, 0, 4e-3],"
                                " initial: [0, 0, 0, 0, 1.5707963, 0], substeps: 0}\n"
                                "gaps: {plugin: sensor.capacitive_gap}\n");
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}});
  EXPECT_TRUE(configure_refused_naming(h, {"mass_kg", "inertia_kg_m2", "singularity", "substeps"}));
}

TEST(RigidBody6, DerivativeIsTheKinematicsOfRbfAndEBitForBit) {
  // derivative() computes each attitude sine and cosine once for R_BF and E; the rates it gives
  // must be the bits of R_BF v and E Omega built from rotation_body_to_fixed() and
  // euler_rate_matrix() (each computing its own), so sharing them changed no result.
  const rb::Physics physics{};
  const rb::Input u{0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (int k = 0; k < 200; ++k) {
    const double a = 0.013 * k;
    const rb::State x{1e-3, -2e-3, 5e-4, 0.3 * std::sin(a), 0.4 * std::cos(1.3 * a), 2.0 * std::sin(0.7 * a),
                      0.01, -0.02, 0.03, 0.5 * std::cos(a), -0.4, 0.3 * std::sin(2 * a)};
    rb::State dxdt{};
    rb::derivative(physics, x, u, dxdt);
    const rb::Matrix3 r = rb::rotation_body_to_fixed(x[rb::kPhi], x[rb::kTheta], x[rb::kPsi]);
    const rb::Matrix3 e = rb::euler_rate_matrix(x[rb::kPhi], x[rb::kTheta]);
    for (std::size_t i = 0; i < 3; ++i) {
      const double translation = r[i][0] * x[rb::kU] + r[i][1] * x[rb::kV] + r[i][2] * x[rb::kW];
      const double attitude = e[i][0] * x[rb::kP] + e[i][1] * x[rb::kQ] + e[i][2] * x[rb::kR];
      ASSERT_EQ(dxdt[rb::kX + i], translation) << "k = " << k << ", row " << i;
      ASSERT_EQ(dxdt[rb::kPhi + i], attitude) << "k = " << k << ", row " << i;
    }
  }
}

}  // namespace
