#include "source_tunable_checks.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "lode/sdk/testing/allocation_counter.hpp"

namespace lode::plugins::source::testing {

using lode::testing::BlockHarness;

void expect_tunables(const Tunables& block, const std::vector<std::pair<std::string, std::string>>& names_and_units) {
  const std::vector<Tunable> t = block.tunables();
  ASSERT_EQ(t.size(), names_and_units.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(t[i].name, names_and_units[i].first) << "tunable " << i;
    EXPECT_EQ(t[i].unit, names_and_units[i].second) << t[i].name;
  }
}

void expect_refusals_change_nothing(const std::string& plugin, const std::string& params, double rate_hz,
                                    const std::function<void(Tunables& block)>& refuse) {
  BlockHarness h(plugin, params, rate_hz);
  BlockHarness twin(plugin, params, rate_hz);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(twin.configure());
  ASSERT_TRUE(h.activate());
  ASSERT_TRUE(twin.activate());
  for (int k = 0; k < 300; ++k) {
    if (k == 100) refuse(h.tunables());
    h.step();
    twin.step();
    ASSERT_EQ(h.output("out")[0], twin.output("out")[0]) << k;
  }
}

void expect_set_tunable_allocates_nothing(BlockHarness& h, std::size_t index, double a, double b) {
  Tunables& block = h.tunables();
  const char* why = "";
  int accepted = 0;
  const auto before = lode::testing::allocation_count();
  for (int k = 0; k < 1000; ++k) {
    accepted += block.set_tunable(index, (k % 2) ? a : b, why) ? 1 : 0;
    (void)block.set_tunable(index, std::nan(""), why);
    (void)block.set_tunable(1000000, 1.0, why);
    h.step();
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
  EXPECT_EQ(accepted, 1000);
}

}  // namespace lode::plugins::source::testing
