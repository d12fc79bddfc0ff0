// controller.discrete_tf: eq. 4.48-4.51 by matched pole-zero, the printed difference
// equation, Tustin with prewarp, the closed loop with the ZOH double integrator (Kawato 2005),
// output clamp with anti-windup, configuration errors, faults, no allocation in step().
#include "discrete_tf.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/harness.hpp"


namespace lode::plugins {
namespace {

using lode::testing::BlockHarness;
using Complex = std::complex<double>;

constexpr double kRateHz = 800.0;
constexpr double kPeriodS = 1.0 / kRateHz;
constexpr double kMassKg = 6.20;          // eq. 4.44
constexpr double kInertiaKgM2 = 0.054;    // eq. 4.46
const Elements kPose{{"x", "m"}, {"y", "m"}, {"theta_z", "rad"}};

// The thesis controllers, eq. 4.48 and 4.50, as axis maps.
const char* const kThesisAxes = R"(
axes:
  - {zeros_s: [-8.31, -10], poles_s: [0, -1134], gain: 4.09e5, discretization: matched}
  - {zeros_s: [-8.31, -10], poles_s: [0, -1134], gain: 4.09e5}
  - {zeros_s: [-8.31, -10], poles_s: [0, -1134], gain: 7.6e3, discretization: matched}
output_units: [N, N, N*m]
)";

/// The printed D(z) of eq. 4.49 / 4.51 given directly.
std::string printed_axis(double gain) {
  char buffer[200];
  std::snprintf(buffer, sizeof buffer, "  - {num_z: [%.17g, %.17g, %.17g], den_z: [1, -1.2423, 0.2423]}\n", gain,
                -1.9773 * gain, 0.977428 * gain);
  return buffer;
}

const Json& member(const Json& j, const std::string& key) {
  const Json* m = j.find(key);
  if (m == nullptr) {
    static const Json null;
    ADD_FAILURE() << "describe() has no '" << key << "'";
    return null;
  }
  return *m;
}

std::vector<double> numbers_of(const Json& array) {
  std::vector<double> out;
  for (const Json& e : array.elements()) out.push_back(e.as_number());
  return out;
}

/// num/den (descending powers) of axis i from describe().
discrete_tf::Design described_design(const Json& describe, std::size_t axis) {
  const Json& a = member(describe, "axes").elements().at(axis);
  discrete_tf::Design d;
  d.num = numbers_of(member(a, "num_z"));
  d.den = numbers_of(member(a, "den_z"));
  return d;
}

// --- 1. Matched pole-zero of eq. 4.48 and 4.50 ---------------------------------------------

TEST(ControllerDiscreteTf, MatchedPoleZeroReproducesEq449And451) {
  BlockHarness h("controller.discrete_tf", kThesisAxes, kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Json d = h.describe();
  const auto& axes = member(d, "axes").elements();
  ASSERT_EQ(axes.size(), 3u);
  const double printed_gain[] = {2.236e5, 2.236e5, 4.155e3};
  for (std::size_t i = 0; i < 3; ++i) {
    const Json& z = member(axes[i], "z_domain");
    const std::vector<double> num = numbers_of(member(z, "numerator_monic"));
    const std::vector<double> den = numbers_of(member(z, "denominator_monic"));
    const double gain = member(z, "gain").as_number();
    std::printf("axis %zu: D(z) = %.5g (z^2 %+.6f z %+.6f) / (z^2 %+.6f z %+.6f); printed %.4g, %+.2f %%\n", i, gain,
                num[1], num[2], den[1], den[2], printed_gain[i], 100.0 * (gain / printed_gain[i] - 1.0));
    ASSERT_EQ(num.size(), 3u);
    ASSERT_EQ(den.size(), 3u);
    // 4 significant digits: relative error below 5e-4.
    const double printed_num[] = {1.0, -1.9773, 0.977428};
    const double printed_den[] = {1.0, -1.2423, 0.2423};
    for (std::size_t k = 0; k < 3; ++k) {
      EXPECT_NEAR(num[k], printed_num[k], 5e-4 * std::abs(printed_num[k])) << "axis " << i << " b" << k;
      EXPECT_NEAR(den[k], printed_den[k], 5e-4 * std::abs(printed_den[k])) << "axis " << i << " a" << k;
    }
    EXPECT_NEAR(gain, printed_gain[i], 0.015 * printed_gain[i]) << "axis " << i;
    EXPECT_EQ(member(axes[i], "method").as_string(), "matched");
  }
  // Matching the velocity constant of eq. 4.48 gives 2.211e5 exactly (eq. 4.49 prints 2.236e5, +1.1 %).
  EXPECT_NEAR(member(member(axes[0], "z_domain"), "gain").as_number(), 2.211e5, 0.0005 * 2.211e5);
  EXPECT_EQ(member(member(axes[0], "gain_matching"), "k").as_number(), 1.0);
  // Ratio of the theta and X gains = 7.6e3/4.09e5 (same factors).
  EXPECT_NEAR(member(member(axes[2], "z_domain"), "gain").as_number() /
                  member(member(axes[0], "z_domain"), "gain").as_number(),
              7.6e3 / 4.09e5, 1e-12);
}

TEST(ControllerDiscreteTf, MatchedFastVariantZeros) {
  // Optional check (eq. 5.4): the "fast" numerator z^2 - 1.9204 z + 0.921233 has zeros at
  // z = 0.98761, 0.93279 <-> s = 800 ln z = -9.98 and -55.7 rad/s; matching them back gives it.
  const double s1 = kRateHz * std::log(0.98761);
  const double s2 = kRateHz * std::log(0.93279);
  auto d = discrete_tf::matched_pole_zero({s1, s2}, {0.0, -1134.0}, 1.0, kPeriodS);
  ASSERT_TRUE(d) << d.error();
  const std::vector<double> num = d->monic_numerator();
  EXPECT_NEAR(num[1], -1.9204, 5e-4 * 1.9204);
  EXPECT_NEAR(num[2], 0.921233, 5e-4 * 0.921233);
}

// --- 2. The printed difference equation ---------------------------------------------------

TEST(ControllerDiscreteTf, DifferenceEquationMatchesPrintedRecursion) {
  const double gain = 2.236e5;
  BlockHarness h("controller.discrete_tf", "axes:\n" + printed_axis(gain) + "output_units: [N]\n", kRateHz);
  h.feed("measurement", {{"x", "m"}});
  h.feed("reference", {{"x_ref", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  EXPECT_EQ(h.output_elements("out")[0].name, "u_x");
  EXPECT_EQ(h.output_elements("out")[0].unit, "N");
  auto measurement = h.input("measurement");
  auto reference = h.input("reference");
  auto out = h.output("out");

  std::mt19937 rng(4711);
  std::uniform_real_distribution<double> uniform(-1e-4, 1e-4);
  double e1 = 0, e2 = 0, u1 = 0, u2 = 0, worst = 0, largest = 0;
  for (int k = 0; k < 5000; ++k) {
    reference[0] = uniform(rng);
    measurement[0] = uniform(rng);
    const double e = reference[0] - measurement[0];
    ASSERT_EQ(h.step(), StepStatus::ok);
    // u_k = 1.2423 u_{k-1} - 0.2423 u_{k-2} + K (e_k - 1.9773 e_{k-1} + 0.977428 e_{k-2})
    const double u = 1.2423 * u1 - 0.2423 * u2 + gain * (e - 1.9773 * e1 + 0.977428 * e2);
    worst = std::max(worst, std::abs(out[0] - u));
    largest = std::max(largest, std::abs(u));
    e2 = e1;
    e1 = e;
    u2 = u1;
    u1 = u;
  }
  std::printf("difference equation: worst |u - u_printed| = %.3e N over 5000 samples (max |u| = %.3g N)\n", worst,
              largest);
  EXPECT_LT(worst, 1e-10 * largest);
}

// --- 3. Tustin with prewarp ----------------------------------------------------------------

/// Steady-state complex gain of the block at f_hz: feed e_k = cos(w k T) and take one DFT bin
/// over a whole number of periods once the transient has died out.
Complex measured_response(BlockHarness& h, double f_hz) {
  auto measurement = h.input("measurement");
  auto out = h.output("out");
  const double w = 2.0 * std::numbers::pi * f_hz;
  Complex u_bin = 0.0;
  Complex e_bin = 0.0;
  for (int k = 0; k < 1600; ++k) {
    const double e = std::cos(w * k * kPeriodS);
    measurement[0] = -e;  // no reference: e = -measurement
    EXPECT_EQ(h.step(), StepStatus::ok);
    if (k >= 800) {
      const Complex phasor = std::polar(1.0, -w * k * kPeriodS);
      u_bin += out[0] * phasor;
      e_bin += e * phasor;
    }
  }
  return u_bin / e_bin;
}

TEST(ControllerDiscreteTf, TustinPrewarpMatchesContinuousResponseAtPrewarpFrequency) {
  // First-order lag D(s) = a / (s + a), a = 2 pi 40 rad/s; prewarp at 100 Hz (8 samples/period).
  const double a = 2.0 * std::numbers::pi * 40.0;
  const double f0 = 100.0;
  const Complex continuous = a / (Complex(0.0, 2.0 * std::numbers::pi * f0) + a);
  auto response = [&](const std::string& extra) {
    char yaml[300];
    std::snprintf(yaml, sizeof yaml, "axes:\n  - {poles_s: [%.17g], gain: %.17g, discretization: tustin%s}\n"
                  "output_units: [N]\n", -a, a, extra.c_str());
    BlockHarness h("controller.discrete_tf", yaml, kRateHz);
    h.feed("measurement", {{"x", "m"}});
    EXPECT_TRUE(h.configure()) << h.diagnostics();
    EXPECT_TRUE(h.activate());
    const Complex measured = measured_response(h, f0);
    const Complex from_coefficients =
        described_design(h.describe(), 0).evaluate(std::polar(1.0, 2.0 * std::numbers::pi * f0 * kPeriodS));
    EXPECT_LT(std::abs(measured - from_coefficients), 1e-9) << "the block runs the described D(z)";
    return measured;
  };
  const Complex prewarped = response(", prewarp_hz: 100");
  const Complex plain = response("");
  std::printf("at %.0f Hz: D(jw) = %.9f%+.9fj, prewarped D(z) = %.9f%+.9fj (|err| %.1e), plain Tustin |err| %.1e\n",
              f0, continuous.real(), continuous.imag(), prewarped.real(), prewarped.imag(),
              std::abs(prewarped - continuous), std::abs(plain - continuous));
  EXPECT_LT(std::abs(prewarped - continuous), 1e-9);
  EXPECT_GT(std::abs(plain - continuous), 1e-2) << "without prewarp the responses differ (the test can fail)";

  // Also exact at DC (Tustin maps s = 0 to z = 1) and the pole maps to (c + p)/(c - p).
  auto d = discrete_tf::tustin({}, {-a}, a, kPeriodS, f0);
  ASSERT_TRUE(d) << d.error();
  EXPECT_NEAR(std::abs(d->evaluate(1.0)), 1.0, 1e-12);
}

// --- 4. Closed loop with the ZOH double integrator ------------------------------------------

struct LoopFigures {
  double crossover_hz = NAN;
  double phase_margin_deg = NAN;
  double largest_pole = NAN;
};

/// L(z) = D(z) G(z), G(z) = T^2 (z + 1) / (2 m (z - 1)^2) (ZOH of 1/(m s^2)).
LoopFigures loop_figures(const discrete_tf::Design& d, double mass) {
  auto plant = [&](Complex z) { return kPeriodS * kPeriodS * (z + 1.0) / (2.0 * mass * (z - 1.0) * (z - 1.0)); };
  auto loop = [&](double f) {
    const Complex z = std::polar(1.0, 2.0 * std::numbers::pi * f * kPeriodS);
    return d.evaluate(z) * plant(z);
  };
  LoopFigures r;
  // |L| falls through 1 once between 0.5 and 200 Hz for these loops: bracket, then bisect.
  double lo = 0.5;
  double hi = 200.0;
  if (std::abs(loop(lo)) < 1.0 || std::abs(loop(hi)) > 1.0) return r;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (std::abs(loop(mid)) > 1.0 ? lo : hi) = mid;
  }
  r.crossover_hz = 0.5 * (lo + hi);
  r.phase_margin_deg = 180.0 + std::arg(loop(r.crossover_hz)) * 180.0 / std::numbers::pi;
  // Closed-loop characteristic polynomial 2 m (z - 1)^2 den(z) + T^2 (z + 1) num(z).
  const std::vector<double> plant_den{2.0 * mass, -4.0 * mass, 2.0 * mass};
  const std::vector<double> plant_num{kPeriodS * kPeriodS, kPeriodS * kPeriodS};
  auto multiply = [](const std::vector<double>& p, const std::vector<double>& q) {
    std::vector<double> out(p.size() + q.size() - 1, 0.0);
    for (std::size_t i = 0; i < p.size(); ++i)
      for (std::size_t j = 0; j < q.size(); ++j) out[i + j] += p[i] * q[j];
    return out;
  };
  std::vector<double> a = multiply(plant_den, d.den);
  std::vector<double> b = multiply(plant_num, d.num);
  for (std::size_t i = 0; i < b.size(); ++i) a[a.size() - b.size() + i] += b[i];
  r.largest_pole = 0.0;
  for (const Complex& p : discrete_tf::poly_roots(a)) r.largest_pole = std::max(r.largest_pole, std::abs(p));
  return r;
}

TEST(ControllerDiscreteTf, ClosedLoopWithZohDoubleIntegrator) {
  BlockHarness h("controller.discrete_tf",
                 "axes:\n" + printed_axis(2.236e5) + printed_axis(2.236e5) + printed_axis(4.155e3) +
                     "output_units: [N, N, N*m]\n",
                 kRateHz);
  h.feed("measurement", kPose);
  h.feed("reference", {{"x_ref", "m"}, {"y_ref", "m"}, {"theta_ref", "rad"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  BlockHarness matched("controller.discrete_tf", kThesisAxes, kRateHz);
  matched.feed("measurement", kPose);
  ASSERT_TRUE(matched.configure()) << matched.diagnostics();

  struct Case {
    const char* name;
    discrete_tf::Design design;
    double mass;
    double spec_crossover_hz;  // derived by hand from the printed D(z), discrete loop
    double spec_phase_margin_deg;
  };
  const Case cases[] = {
      {"X/Y printed D(z)", described_design(h.describe(), 0), kMassKg, 9.56, 67.1},
      {"theta printed D(z)", described_design(h.describe(), 2), kInertiaKgM2, 19.9, 69.9},
      {"X/Y matched (2.211e5)", described_design(matched.describe(), 0), kMassKg, NAN, NAN},
      {"theta matched", described_design(matched.describe(), 2), kInertiaKgM2, NAN, NAN},
  };
  for (const Case& c : cases) {
    const LoopFigures f = loop_figures(c.design, c.mass);
    std::printf("%-22s crossover %.3f Hz, phase margin %.2f deg, largest closed-loop |z| %.6f (ref %.2f Hz, %.1f deg)\n",
                c.name, f.crossover_hz, f.phase_margin_deg, f.largest_pole, c.spec_crossover_hz,
                c.spec_phase_margin_deg);
    EXPECT_LT(f.largest_pole, 1.0) << c.name << ": every closed-loop pole inside the unit circle";
    if (!std::isnan(c.spec_crossover_hz)) {
      EXPECT_NEAR(f.crossover_hz, c.spec_crossover_hz, 0.01 * c.spec_crossover_hz) << c.name;
      EXPECT_NEAR(f.phase_margin_deg, c.spec_phase_margin_deg, 0.5) << c.name;
    }
  }

  // And in the time domain through the block: 100 um X step and 1 mrad theta step on the
  // simulated ZOH plants x_k = 2 x_{k-1} - x_{k-2} + T^2/(2m) (u_{k-1} + u_{k-2}).
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");
  auto reference = h.input("reference");
  auto out = h.output("out");
  const double step[3] = {100e-6, 0.0, 1e-3};
  const double mass[3] = {kMassKg, kMassKg, kInertiaKgM2};
  double x[3][3] = {};  // x_k, x_{k-1}, x_{k-2}
  double u[3][2] = {};  // u_{k-1}, u_{k-2}
  double peak[3] = {};
  for (int k = 0; k < 2400; ++k) {
    for (std::size_t i = 0; i < 3; ++i) {
      x[i][2] = x[i][1];
      x[i][1] = x[i][0];
      x[i][0] = 2.0 * x[i][1] - x[i][2] + kPeriodS * kPeriodS / (2.0 * mass[i]) * (u[i][0] + u[i][1]);
      measurement[i] = x[i][0];
      reference[i] = step[i];
      peak[i] = std::max(peak[i], x[i][0]);
    }
    ASSERT_EQ(h.step(), StepStatus::ok);
    for (std::size_t i = 0; i < 3; ++i) {
      u[i][1] = u[i][0];
      u[i][0] = out[i];
    }
  }
  for (std::size_t i : {0u, 2u}) {
    std::printf("axis %zu closed-loop step: final %.6g (reference %.3g), overshoot %.1f %%\n", i, x[i][0], step[i],
                100.0 * (peak[i] / step[i] - 1.0));
    EXPECT_NEAR(x[i][0], step[i], 1e-4 * step[i]) << "settles on the reference (integral action)";
  }
  EXPECT_EQ(x[1][0], 0.0);
}

// --- 5. Output limit and anti-windup --------------------------------------------------------

TEST(ControllerDiscreteTf, OutputLimitClampsAndAntiWindupReleases) {
  const double limit = 20.0;  // N
  BlockHarness h("controller.discrete_tf",
                 "axes:\n  - {zeros_s: [-8.31, -10], poles_s: [0, -1134], gain: 4.09e5}\n"
                 "output_units: [N]\noutput_limit: 20\n",
                 kRateHz);
  h.feed("measurement", {{"x", "m"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");
  auto out = h.output("out");
  const discrete_tf::Design design = described_design(h.describe(), 0);

  // The same controller without anti-windup (only the output clamped), for comparison.
  double s[2] = {0.0, 0.0};
  auto naive = [&](double e) {
    const double u = design.num[0] * e + s[0];
    s[0] = design.num[1] * e - design.den[1] * u + s[1];
    s[1] = design.num[2] * e - design.den[2] * u;
    return std::clamp(u, -limit, limit);
  };

  // 20 s of a large error (1 mm): the linear output would be ~30 N/s * t from the integrator
  // (velocity constant 2.997e4 N/(m s)) plus the lead terms, ~600 N at the end.
  double largest = 0.0;
  for (int k = 0; k < 16000; ++k) {
    measurement[0] = -1e-3;
    ASSERT_EQ(h.step(), StepStatus::ok);
    naive(1e-3);
    largest = std::max(largest, std::abs(out[0]));
  }
  EXPECT_LE(largest, limit);
  EXPECT_EQ(out[0], limit);

  // Then an error of the opposite sign (-0.1 mm): the output must leave the limit at once.
  int released_after = -1;
  int naive_released_after = -1;
  double at_release = NAN;
  double after_1s = NAN;
  for (int k = 0; k < 2400; ++k) {
    measurement[0] = 1e-4;  // e = -0.1 mm
    ASSERT_EQ(h.step(), StepStatus::ok);
    const double u_naive = naive(-1e-4);
    if (released_after < 0 && out[0] < limit) {
      released_after = k;
      at_release = out[0];
    }
    if (naive_released_after < 0 && u_naive < limit) naive_released_after = k;
    if (k == 799) after_1s = out[0];
    EXPECT_LE(std::abs(out[0]), limit);
  }
  std::printf("after 20 s at the +%g N limit, e = -0.1 mm: the output leaves the limit after %d samples with "
              "anti-windup (%.2f N: the lead's kick; %.2f N after 1 s, %.2f N after 3 s); with the clamp alone: %s\n",
              limit, released_after, at_release, after_1s, out[0],
              naive_released_after < 0 ? "still saturated after 3 s" : "released");
  ASSERT_GE(released_after, 0);
  EXPECT_LE(released_after, 2);
  // The integrator kept only what reached the limit (~13 N) and now unwinds at ~3 N/s.
  EXPECT_LT(after_1s, 0.9 * limit);
  EXPECT_LT(out[0], after_1s - 3.0) << "the integrator unwinds with the negative error";
  EXPECT_LT(naive_released_after, 0) << "the scenario winds a clamp without anti-windup up (test can fail)";
}

TEST(ControllerDiscreteTf, UnsaturatedOutputIsUnaffectedByTheLimit) {
  auto run = [](const std::string& limit) {
    BlockHarness h("controller.discrete_tf",
                   "axes:\n  - {zeros_s: [-8.31, -10], poles_s: [0, -1134], gain: 4.09e5}\noutput_units: [N]\n" +
                       limit,
                   kRateHz);
    h.feed("measurement", {{"x", "m"}});
    EXPECT_TRUE(h.configure()) << h.diagnostics();
    EXPECT_TRUE(h.activate());
    auto measurement = h.input("measurement");
    std::vector<double> u;
    for (int k = 0; k < 800; ++k) {
      measurement[0] = 1e-6 * std::sin(0.05 * k);
      EXPECT_EQ(h.step(), StepStatus::ok);
      u.push_back(h.output("out")[0]);
    }
    return u;
  };
  const std::vector<double> free = run("");
  const std::vector<double> limited = run("output_limit: [1000]\n");
  EXPECT_EQ(free, limited);
}

// --- errors, faults, allocation -------------------------------------------------------------

TEST(ControllerDiscreteTf, ReferenceUnitsMustEqualMeasurementUnits) {
  BlockHarness h("controller.discrete_tf", kThesisAxes, kRateHz);
  h.feed("measurement", kPose);
  h.feed("reference", {{"x_ref", "m"}, {"y_ref", "mm"}, {"theta_ref", "rad"}});
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("blocks.dut.inputs"), std::string::npos) << h.diagnostics();
  EXPECT_NE(h.diagnostics().find("'mm'"), std::string::npos) << h.diagnostics();
}

TEST(ControllerDiscreteTf, BadParametersAreLocatedErrors) {
  struct Case {
    std::string yaml;
    const char* field;
  };
  const Case cases[] = {
      {"axes:\n  - {zeros_s: [-1, -2], poles_s: [-3], gain: 1}\noutput_units: [N]\n", "blocks.dut.axes[0]"},
      {"axes:\n  - {poles_s: [-3], gain: 1, num_z: [1], den_z: [1]}\noutput_units: [N]\n", "blocks.dut.axes[0]"},
      {"axes:\n  - {poles_s: [-3], gain: 1, prewarp_hz: 10}\noutput_units: [N]\n", "blocks.dut.axes[0].prewarp_hz"},
      {"axes:\n  - {poles_s: [-3], gain: 1, discretization: tustin, prewarp_hz: 400}\noutput_units: [N]\n",
       "blocks.dut.axes[0]"},
      {"axes:\n  - {poles_s: [-3], gain: 1, discretization: zoh}\noutput_units: [N]\n",
       "blocks.dut.axes[0].discretization"},
      {"axes:\n  - {num_z: [1, 2, 3], den_z: [1, 0.5]}\noutput_units: [N]\n", "blocks.dut.axes[0].den_z"},
      {"axes:\n  - {num_z: [1], den_z: [0, 1]}\noutput_units: [N]\n", "blocks.dut.axes[0].den_z"},
      {"axes:\n  - {poles_s: [-3], gain: 1}\n", "blocks.dut.output_units"},
      {"axes:\n  - {poles_s: [-3], gain: 1}\noutput_units: [N, N]\n", "blocks.dut.output_units"},
      {"axes:\n  - {poles_s: [-3], gain: 1}\n  - {poles_s: [-3], gain: 1}\noutput_units: [N, N]\n", "blocks.dut.axes"},
      {"axes:\n  - {poles_s: [-3], gain: 1}\noutput_units: [N]\noutput_limit: [-1]\n", "blocks.dut.output_limit"},
      {"axes:\n  - {poles_s: [-1, -1, -1, -1, -1, -1, -1, -1, -1], gain: 1}\noutput_units: [N]\n",
       "blocks.dut.axes[0]"},
  };
  for (const Case& c : cases) {
    BlockHarness h("controller.discrete_tf", c.yaml, kRateHz);
    h.feed("measurement", {{"x", "m"}});
    EXPECT_FALSE(h.configure()) << c.yaml;
    EXPECT_NE(h.diagnostics().find(c.field), std::string::npos) << c.yaml << "\n" << h.diagnostics();
  }
}

TEST(ControllerDiscreteTf, NonFiniteInputFaultsAndKeepsState) {
  BlockHarness h("controller.discrete_tf", kThesisAxes, kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");
  measurement[0] = 1e-6;
  ASSERT_EQ(h.step(), StepStatus::ok);
  const double before = h.output("out")[0];
  measurement[2] = std::nan("");
  EXPECT_EQ(h.step(), StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "non-finite measurement or reference");
  EXPECT_EQ(h.output("out")[0], before);
}

TEST(ControllerDiscreteTf, OutputNamesAndDescribe) {
  BlockHarness h("controller.discrete_tf",
                 std::string(kThesisAxes) + "output_names: [fx, fy, tz]\noutput_limit: [50, 50, 2]\n", kRateHz);
  h.feed("measurement", kPose);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  const Elements& out = h.output_elements("out");
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[2].name, "tz");
  EXPECT_EQ(out[2].unit, "N*m");
  const Json d = h.describe();
  const Json& axis = member(d, "axes").elements().at(2);
  EXPECT_EQ(member(axis, "measurement").as_string(), "theta_z");
  EXPECT_EQ(member(axis, "output_limit").as_number(), 2.0);
  EXPECT_EQ(numbers_of(member(member(axis, "s_domain"), "poles")), (std::vector<double>{0.0, -1134.0}));
  EXPECT_EQ(member(member(axis, "z_domain"), "poles").elements().size(), 2u);
  EXPECT_EQ(numbers_of(member(axis, "den_z")).size(), 3u);
}

TEST(ControllerDiscreteTf, StepDoesNotAllocate) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  BlockHarness h("controller.discrete_tf", std::string(kThesisAxes) + "output_limit: 5\n", kRateHz);
  h.feed("measurement", kPose);
  h.feed("reference", {{"x_ref", "m"}, {"y_ref", "m"}, {"theta_ref", "rad"}});
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  auto measurement = h.input("measurement");
  const long before = static_cast<long>(lode::testing::allocation_count());
  for (int k = 0; k < 10000; ++k) {
    measurement[0] = 1e-4 * std::sin(0.01 * k);
    if (h.step() != StepStatus::ok) FAIL() << h.block().fault_reason();
  }
  EXPECT_EQ(static_cast<long>(lode::testing::allocation_count()) - before, 0);
}

}  // namespace
}  // namespace lode::plugins
