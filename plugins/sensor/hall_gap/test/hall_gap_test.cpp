// sensor.hall_gap: the spot values and monotonicity of eq. 16 (against a table evaluated by
// hand, to +-0.01 mm), the bracketed reading of eq. 15, forward/inverse consistency with the
// direct conversion, the Jacobian, clamping, the `gap` output, and the YAML path through io.sim.
#include "hall_gap.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/require.hpp"

namespace {

using lode::plugins::HallGap;
namespace hall = lode::plugins::hall;


// Eq. 16 by hand: C_H [V], M_H [mm], slope dM_H/dC_H [mm/V], to 0.01 mm / 0.1 mm/V.
struct SpotValue {
  double c_h, distance_mm, slope_mm_per_v;
};
constexpr std::array<SpotValue, 9> kHandComputedTable{{{0.0, 46.9, -183.9},
                                                {0.1, 33.69, -90.7},
                                                {0.2, 27.15, -46.0},
                                                {0.3, 23.61, -27.6},
                                                {0.4, 21.27, -20.0},
                                                {0.5, 19.55, -14.4},
                                                {0.6, 18.41, -8.7},
                                                {0.7, 17.65, -7.9},
                                                {0.8, 16.29, -23.4}}};

TEST(HallConversion, SpotValuesOfEq16ByHand) {
  const hall::Conversion c = hall::Conversion::paper();
  EXPECT_DOUBLE_EQ(c.distance_mm.value(0.0), 46.9);  // "no magnet field"
  for (const SpotValue& s : kHandComputedTable) {
    EXPECT_NEAR(c.distance_mm.value(s.c_h), s.distance_mm, 0.01) << "C_H = " << s.c_h;
    EXPECT_NEAR(c.distance_mm.slope(s.c_h), s.slope_mm_per_v, 0.05) << "C_H = " << s.c_h;
  }
  // Past 0.8 V the polynomial falls away (11.83 mm at 0.9 V): not a valid reading.
  EXPECT_NEAR(c.distance_mm.value(0.9), 11.83, 0.01);
}

TEST(HallConversion, MonotonicDecreasingOnTheValidRange) {
  const hall::Conversion c = hall::Conversion::paper();
  double worst = -1e9;
  double previous = c.distance_mm.value(0.0);
  for (int k = 1; k <= 8000; ++k) {
    const double x = 0.8 * k / 8000.0;
    const double d = c.distance_mm.value(x);
    EXPECT_LT(d, previous) << "at C_H = " << x;
    previous = d;
    worst = std::max(worst, c.distance_mm.slope(x));
  }
  std::printf("largest slope of M_H on [0, 0.8] V: %.3f mm/V (strictly decreasing)\n", worst);
  EXPECT_LT(worst, -7.0);
  EXPECT_NEAR(c.max_distance_slope(), worst, 0.01);
  EXPECT_NEAR(c.farthest_mm(), 46.9, 1e-12);
  EXPECT_NEAR(c.nearest_mm(), 16.2902, 1e-3);
}

TEST(HallConversion, BracketedReadingOfEq15) {
  const hall::Conversion c = hall::Conversion::paper();
  // The coil term is tiny as printed: at most 0.28 mV at v = 3 V.
  EXPECT_NEAR(c.coil_v.value(3.0) - 2.544, 1.299e-6 * 9 + 9.05e-5 * 3, 1e-15);
  EXPECT_LT(c.coil_v.value(3.0) - 2.544, 0.3e-3);
  // A Hall output 0.2 V above its quiescent + coil level reads 27.15 mm.
  const double v = 1.7;
  bool clamped = true;
  EXPECT_NEAR(c.direct_gap_m(2.544 + 1.299e-6 * v * v + 9.05e-5 * v + 0.2, v, clamped), 27.1525e-3, 1e-7);
  EXPECT_FALSE(clamped);
  // The literal reading C_H = v_hall + 2.544 - ... would be about 5 V, where eq. 16 is absurd.
  EXPECT_LT(c.distance_mm.value(2.744 + 2.544), -1e4);
}

TEST(HallConversion, InverseOfTheCharacteristic) {
  const hall::Conversion c = hall::Conversion::paper();
  double worst = 0.0;
  for (double d = 16.3; d < 46.9; d += 0.01) {
    const double c_h = c.compensated_for_distance(d);
    worst = std::max(worst, std::abs(c.distance_mm.value(c_h) - d));
  }
  EXPECT_LT(worst, 1e-10) << "mm";
  EXPECT_EQ(c.compensated_for_distance(50.0), 0.0);
  EXPECT_EQ(c.compensated_for_distance(10.0), 0.8);
}

std::unique_ptr<HallGap> configured(HallGap::Output output) {
  auto model = std::make_unique<HallGap>();
  model->apply(hall::Conversion::paper(), output, output == HallGap::Output::gap ? "gap" : "hall");
  return model;
}

TEST(HallGapModel, ElementsAndUnits) {
  const auto v_owner = configured(HallGap::Output::hall_voltage);
  const HallGap& v = *v_owner;
  ASSERT_EQ(v.state_elements().size(), 2u);
  EXPECT_EQ(v.state_elements()[0].name, "gap");
  EXPECT_EQ(v.state_elements()[0].unit, "m");
  EXPECT_EQ(v.state_elements()[1].name, "coil_voltage");
  EXPECT_EQ(v.state_elements()[1].unit, "V");
  ASSERT_EQ(v.channels().size(), 1u);
  EXPECT_EQ(v.channels()[0].name, "hall");
  EXPECT_EQ(v.channels()[0].unit, "V");
  const auto g_owner = configured(HallGap::Output::gap);
  const HallGap& g = *g_owner;
  ASSERT_EQ(g.state_elements().size(), 1u);
  EXPECT_EQ(g.channels()[0].name, "gap");
  EXPECT_EQ(g.channels()[0].unit, "m");
}

TEST(HallGapModel, ForwardModelInvertsTheDirectConversion) {
  // What the simulated sensor outputs, fed to eq. 14, gives back the gap (any coil voltage).
  const auto model_owner = configured(HallGap::Output::hall_voltage);
  const HallGap& model = *model_owner;
  const hall::Conversion& c = model.conversion();
  double worst = 0.0;
  for (double d = 0.0165; d < 0.0468; d += 0.0001) {
    for (double v : {0.0, 0.5, 1.7, 3.0}) {
      const std::array<double, 2> state{d, v};
      double hall_v = 0.0;
      model.evaluate(state.data(), &hall_v);
      bool clamped = true;
      worst = std::max(worst, std::abs(c.direct_gap_m(hall_v, v, clamped) - d));
      EXPECT_FALSE(clamped);
    }
  }
  EXPECT_LT(worst, 1e-12) << "m";
  // At 30 mm the Hall output sits ~0.137 V above the quiescent level.
  const std::array<double, 2> state{0.030, 0.0};
  double hall_v = 0.0;
  model.evaluate(state.data(), &hall_v);
  EXPECT_NEAR(hall_v - 2.544, c.compensated_for_distance(30.0), 1e-15);
  EXPECT_GT(hall_v - 2.544, 0.13);
  EXPECT_LT(hall_v - 2.544, 0.15);
}

TEST(HallGapModel, JacobianMatchesCentralDifferences) {
  const auto model_owner = configured(HallGap::Output::hall_voltage);
  const HallGap& model = *model_owner;
  double worst = 0.0;
  for (double d = 0.017; d < 0.046; d += 0.0005) {
    for (double v : {0.5, 2.0}) {
      std::array<double, 2> state{d, v};
      double y = 0.0;
      std::array<double, 2> H{};
      model.jacobian(state.data(), &y, H.data());
      for (std::size_t j = 0; j < 2; ++j) {
        const double h = j == 0 ? 1e-7 : 1e-4;
        std::array<double, 2> plus = state, minus = state;
        plus[j] += h;
        minus[j] -= h;
        double yp = 0.0, ym = 0.0;
        model.evaluate(plus.data(), &yp);
        model.evaluate(minus.data(), &ym);
        const double numeric = (yp - ym) / (2 * h);
        worst = std::max(worst, std::abs(H[j] - numeric) / std::abs(numeric));
      }
    }
  }
  EXPECT_LT(worst, 1e-5);
}

TEST(HallGapModel, FlatOutsideTheConversionRange) {
  const auto model_owner = configured(HallGap::Output::hall_voltage);
  const HallGap& model = *model_owner;
  for (double d : {0.012, 0.0160, 0.048, 0.060}) {
    std::array<double, 2> state{d, 1.0};
    double y = 0.0;
    std::array<double, 2> H{1, 1};
    model.jacobian(state.data(), &y, H.data());
    EXPECT_EQ(H[0], 0.0) << d;
    const double c_h = y - model.conversion().coil_v.value(1.0);
    EXPECT_NEAR(c_h, d < 0.03 ? 0.8 : 0.0, 1e-15) << d;
  }
}

TEST(HallGapModel, GapOutputIsTheDirectDistance) {
  const auto model_owner = configured(HallGap::Output::gap);
  const HallGap& model = *model_owner;
  const double d = 0.0247;
  double y = 0.0;
  double H = 0.0;
  model.jacobian(&d, &y, &H);
  EXPECT_EQ(y, d);
  EXPECT_EQ(H, 1.0);
  const double far = 0.049;
  model.jacobian(&far, &y, &H);
  EXPECT_NEAR(y, 0.0469, 1e-15);  // what eq. 14 reports at most
  EXPECT_EQ(H, 0.0);
}

TEST(HallGapModel, PointsInOneCallAreEachEvaluatedAsAlone) {
  // evaluate_points() (a UKF's sigma points in one call, each point `stride` doubles after the
  // one before: the estimator's whole state) must give every point the bits evaluate() gives
  // it alone, on both outputs, inside the range and clamped at either end.
  for (const auto output : {HallGap::Output::gap, HallGap::Output::hall_voltage}) {
    const auto model_owner = configured(output);
    const HallGap& model = *model_owner;
    constexpr std::size_t kStride = 3;  // gap, coil voltage, and one element the model does not read
    const std::array<double, 5 * kStride> states{0.0247, 1.0, 9.0,  0.026, 0.5,  9.0, 0.049, -2.0, 9.0,
                                                 0.010,  3.0, 9.0,  0.0301, 0.0, 9.0};
    std::array<double, 5> batch{};
    model.evaluate_points(states.data(), kStride, 5, batch.data());
    for (std::size_t i = 0; i < 5; ++i) {
      double alone = 0.0;
      model.evaluate(states.data() + i * kStride, &alone);
      EXPECT_EQ(batch[i], alone) << "point " << i << (output == HallGap::Output::gap ? ", gap" : ", hall_voltage");
    }
  }
}

TEST(HallGapModel, ClampLimitsFollowTheConversionApplied) {
  // The range ends are taken once per apply(): a model reconfigured with a narrower C_H
  // range clamps and goes flat at the new ends, not at the ones it was constructed with.
  hall::Conversion narrow = hall::Conversion::paper();
  narrow.compensated_min_v = 0.1;  // farthest M_H(0.1) = 33.69 mm
  narrow.compensated_max_v = 0.7;  // nearest M_H(0.7) = 17.65 mm
  HallGap gap_model;
  gap_model.apply(narrow, HallGap::Output::gap, "gap");
  const double far = 0.040;
  double y = 0.0;
  double H = 1.0;
  gap_model.jacobian(&far, &y, &H);
  EXPECT_DOUBLE_EQ(y, 1e-3 * narrow.distance_mm.value(0.1)) << "clamped at the configured farthest distance";
  EXPECT_EQ(H, 0.0);
  const double near = 0.017;
  gap_model.evaluate(&near, &y);
  EXPECT_DOUBLE_EQ(y, 1e-3 * narrow.distance_mm.value(0.7)) << "clamped at the configured nearest distance";

  HallGap volts_model;
  volts_model.apply(narrow, HallGap::Output::hall_voltage, "hall");
  std::array<double, 2> state{0.040, 1.0};
  std::array<double, 2> slope{1.0, 1.0};
  volts_model.jacobian(state.data(), &y, slope.data());
  EXPECT_NEAR(y - narrow.coil_v.value(1.0), 0.1, 1e-15) << "C_H held at the configured minimum";
  EXPECT_EQ(slope[0], 0.0);
}

TEST(HallGapModel, DescribeShowsTheCharacteristic) {
  const auto model_owner = configured(HallGap::Output::hall_voltage);
  const HallGap& model = *model_owner;
  lode::Json out = lode::Json::object();
  model.describe(out);
  const lode::Json* table = out.find("characteristic");
  ASSERT_NE(table, nullptr);
  ASSERT_EQ(table->elements().size(), 9u);
  EXPECT_NEAR(table->elements()[2].find("distance_mm")->as_number(), 27.15, 0.01);
}

// The YAML path: io.sim owns the plant and samples this model (and fails its configuration).
const char* const kPlant = "plant: {plugin: plant.suspension, mass_kg: 6.0e-3, force_b_n_m2_per_a: 4.85e-5}\n";

TEST(HallGapYaml, SimulatedBoardSamplesTheForwardModel) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "io.sim");
  lode::testing::BlockHarness h("io.sim", "plant: plant\nsensors: hall\nnoise_std_v: 0\nadc_bits: 0\n", 2000.0,
                                std::string(kPlant) + "hall: {plugin: sensor.hall_gap}\n");
  h.feed("command", {{"coil_voltage", "V"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  ASSERT_EQ(h.step(), lode::StepStatus::ok);
  const double gap = h.output("truth")[0];
  const double coil = h.output("truth")[1];
  EXPECT_NEAR(gap, 0.026, 1e-15);
  const hall::Conversion c = hall::Conversion::paper();
  bool clamped = true;
  EXPECT_NEAR(c.direct_gap_m(h.output("signals")[0], coil, clamped), gap, 1e-12);
}

TEST(HallGapYaml, ANonMonotonicRangeIsALocatedError) {
  LODE_REQUIRE_PLUGINS("plant.suspension", "io.sim");
  lode::testing::BlockHarness h(
      "io.sim", "plant: plant\nsensors: hall\n", 2000.0,
      std::string(kPlant) +
          "hall: {plugin: sensor.hall_gap, compensated_range_v: [0, 0.95], output: volts, coil_polynomial_v: []}\n");
  h.feed("command", {{"coil_voltage", "V"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("models.hall.output"), std::string::npos) << d;
  EXPECT_NE(d.find("models.hall.coil_polynomial_v: expected 1 to 9 coefficients"), std::string::npos) << d;
  lode::testing::BlockHarness h2("io.sim", "plant: plant\nsensors: hall\n", 2000.0,
                                 std::string(kPlant) +
                                     "hall: {plugin: sensor.hall_gap, distance_polynomial_mm: [100, -50, 40]}\n");
  h2.feed("command", {{"coil_voltage", "V"}});
  EXPECT_FALSE(h2.configure());
  EXPECT_NE(h2.diagnostics().find("models.hall.distance_polynomial_mm: M_H must decrease strictly"), std::string::npos)
      << h2.diagnostics();
}

}  // namespace
