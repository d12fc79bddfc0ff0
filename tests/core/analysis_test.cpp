// The end-of-run analysis of `lode run` on signals with known answers.
#include <gtest/gtest.h>

#include <cmath>

#include "analysis.hpp"

namespace {

using lode::analysis::Series;

TEST(Analysis, SecondOrderStepResponseFigures) {
  // Unit step at t = 0.1 s into a known second-order response: zeta 0.5, wn 50 rad/s.
  const double dt = 1e-4, zeta = 0.5, wn = 50.0;
  const double wd = wn * std::sqrt(1 - zeta * zeta);
  std::vector<double> t;
  Series ref{{{"x", "m"}}, {}}, y{{{"x", "m"}}, {}};
  for (int k = 0; k < 20000; ++k) {
    const double tk = k * dt;
    t.push_back(tk);
    const double r = tk >= 0.1 - 1e-12 ? 1.0 : 0.0;
    ref.values.push_back(r);
    const double tau = tk - 0.1;
    y.values.push_back(tau < 0 ? 0.0
                               : 1 - std::exp(-zeta * wn * tau) *
                                         (std::cos(wd * tau) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(wd * tau)));
  }
  const auto steps = lode::analysis::step_responses(t, ref, y, 0.02);
  ASSERT_EQ(steps.size(), 1u);
  const auto& s = steps[0];
  EXPECT_NEAR(s.time_s, 0.1, 1e-9);
  EXPECT_NEAR(s.overshoot_pct, 100 * std::exp(-M_PI * zeta / std::sqrt(1 - zeta * zeta)), 0.1);  // 16.3 %
  EXPECT_NEAR(s.rise_time_s, 1.64 / wn, 0.002);  // 10-90 % rise of zeta 0.5: 1.64/wn
  EXPECT_NEAR(s.settling_time_s, 0.162, 0.01);   // ~4/(zeta wn) = 0.16 s for 2 %
  EXPECT_NEAR(s.steady_state_error, 0.0, 1e-3);
}

TEST(Analysis, WindowStatsOfDifference) {
  std::vector<double> t = {0, 1, 2, 3};
  Series a{{{"x", "m"}}, {1, 2, 3, 4}}, b{{{"x", "m"}}, {1, 1, 1, 1}};
  const auto s = lode::analysis::window_stats(t, a, &b, 1, 3);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].samples, 3u);
  EXPECT_DOUBLE_EQ(s[0].mean, 2.0);
  EXPECT_DOUBLE_EQ(s[0].std, 1.0);
  EXPECT_DOUBLE_EQ(s[0].max_abs, 3.0);
}

}  // namespace

namespace {

TEST(AnalysisStreaming, KeepsAtMostMaxStepsAndCountsTheRest) {
  // A square wave of 2000 steps: a day-long run with a stepping reference must not keep
  // every response.
  lode::analysis::StepResponseTracker tracker(1, 1, 0.02, 1000);
  const double dt = 1e-3;
  for (int k = 0; k < 200000; ++k) {
    const double r = (k / 100) % 2 == 0 ? 0.0 : 1.0;
    tracker.add(k * dt, &r, &r);
  }
  const auto steps = tracker.finish();
  EXPECT_EQ(steps.size(), 1000u);
  EXPECT_EQ(tracker.omitted(), 999u);  // 1999 steps in all (the first edge is at k = 100)
  EXPECT_NEAR(steps.front().time_s, 0.1, 1e-12);
  EXPECT_NEAR(steps.back().time_s, 100.0, 1e-9);
}

TEST(AnalysisStreaming, SteadyStateErrorUsesAtMostTheTailCapacity) {
  // One step, then a response that ramps away for 400 000 samples: the last 10 % is 40 000
  // samples, more than the tail kept; the mean is over the last kTailCapacity samples.
  lode::analysis::StepResponseTracker tracker(1, 1, 0.02);
  const std::size_t n = 400000, cap = lode::analysis::StepResponseTracker::kTailCapacity;
  double last = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double r = k >= 10 ? 1.0 : 0.0;
    const double y = k >= 10 ? 1.0 + 1e-6 * static_cast<double>(k) : 0.0;
    tracker.add(static_cast<double>(k), &r, &y);
    last = static_cast<double>(k);
  }
  const auto steps = tracker.finish();
  ASSERT_EQ(steps.size(), 1u);
  // Mean of 1e-6 k over the last `cap` samples.
  const double expected = 1e-6 * (last - 0.5 * static_cast<double>(cap - 1));
  EXPECT_NEAR(steps[0].steady_state_error, expected, 1e-12);
}

}  // namespace
