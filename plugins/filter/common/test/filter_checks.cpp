#include "filter_checks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/plugin_checks.hpp"

namespace lode::plugins::filter::testing {

std::complex<double> component(const std::vector<double>& y, double f_hz, double rate_hz) {
  double ss = 0, sc = 0, cc = 0, ys = 0, yc = 0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    const double s = std::sin(2 * std::numbers::pi * f_hz * static_cast<double>(k) / rate_hz);
    const double c = std::cos(2 * std::numbers::pi * f_hz * static_cast<double>(k) / rate_hz);
    ss += s * s, sc += s * c, cc += c * c, ys += y[k] * s, yc += y[k] * c;
  }
  const double det = ss * cc - sc * sc;
  return {(ys * cc - yc * sc) / det, (yc * ss - ys * sc) / det};
}

lode::math::TransferFunction described_section(const Json& channel) {
  return {lode::testing::numbers_of(lode::testing::member(channel, "b")),
          lode::testing::numbers_of(lode::testing::member(channel, "a"))};
}

double measured_gain(lode::testing::BlockHarness& h, double f_hz, double rate_hz, int settle_cycles) {
  EXPECT_TRUE(h.activate());
  const auto in = h.input("in");
  std::vector<double> out;
  for (int k = 0; k < settle_cycles + 4 * static_cast<int>(rate_hz); ++k) {
    in[0] = std::sin(2 * std::numbers::pi * f_hz * k / rate_hz);
    EXPECT_EQ(h.step(), StepStatus::ok);
    if (k >= settle_cycles) out.push_back(h.output("out")[0]);
  }
  return std::abs(component(out, f_hz, rate_hz));
}

void expect_cycles_allocate_nothing(lode::testing::BlockHarness& h, int cycles, const std::function<void(int k)>& cycle) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  int failed_steps = 0;
  const std::size_t before = lode::testing::allocation_count();
  for (int k = 0; k < cycles; ++k) {
    cycle(k);
    failed_steps += h.step() == StepStatus::ok ? 0 : 1;
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  EXPECT_EQ(failed_steps, 0);
}

void expect_set_tunables_allocate_nothing(lode::testing::BlockHarness& h, int cycles, int expected_accepted,
                                          const std::function<int(Tunables& block, int k)>& cycle) {
  Tunables& block = h.tunables();
  int accepted = 0;
  expect_cycles_allocate_nothing(h, cycles, [&](int k) { accepted += cycle(block, k); });
  EXPECT_EQ(accepted, expected_accepted);
}

void expect_enabled_tunable(const Tunable& t) {
  EXPECT_EQ(t.name, "enabled");
  EXPECT_EQ(t.unit, "bool");
  EXPECT_TRUE(t.integer);
  EXPECT_EQ(t.min, 0.0);
  EXPECT_EQ(t.max, 1.0);
}

}  // namespace lode::plugins::filter::testing
