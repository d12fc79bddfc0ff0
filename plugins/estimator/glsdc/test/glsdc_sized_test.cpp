// estimator.glsdc's sized path (3dof over four channels, compile_time_sizes: true) against the
// generic path on the same measurements: the same bits every tick, the same back-offs and
// singular skips, no allocation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "glsdc_rig.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"

namespace lode::plugins {
namespace {

using namespace glsdc_testing;


/// Pose, covariance and cost of `a` and `b` are the same bits (NaN equal to NaN).
::testing::AssertionResult same_outputs(Rig& a, Rig& b) {
  auto same = [](double u, double v) { return std::memcmp(&u, &v, sizeof u) == 0; };
  for (int i = 0; i < 3; ++i) {
    if (!same(a.pose(i), b.pose(i)))
      return ::testing::AssertionFailure() << "pose " << i << ": " << a.pose(i) << " vs " << b.pose(i);
    for (int j = 0; j < 3; ++j) {
      if (!same(a.covariance(i, j), b.covariance(i, j)))
        return ::testing::AssertionFailure() << "covariance " << i << j << ": " << a.covariance(i, j) << " vs "
                                             << b.covariance(i, j);
    }
  }
  if (!same(a.cost(), b.cost())) return ::testing::AssertionFailure() << "cost: " << a.cost() << " vs " << b.cost();
  return ::testing::AssertionSuccess();
}

TEST(GlsdcSized, SizedPathGivesTheGenericResultsBitForBit) {
  // 3dof over two two-axis sensors (the kawato_planar configuration) runs the sized path;
  // compile_time_sizes: false the generic one. Noisy slow motion with 3 mm jumps (steps that
  // back off), a warm start imported mid-run (the kept factorisation must be dropped): the
  // same pose, covariance and cost bits every tick, the same back-off count, no allocation.
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Truth truth("[1, 5]");
  ASSERT_TRUE(truth.ok());
  std::mt19937_64 rng(21);
  std::normal_distribution<double> noise(0.0, 1e-3);
  std::vector<std::vector<double>> path;
  for (int k = 0; k < 600; ++k) {
    const double jump = (k / 100) % 2 == 1 ? 3e-3 : 0.0;
    std::vector<double> y =
        truth.measure(1e-3 * std::sin(0.01 * k) + jump, 5e-4 * std::cos(0.013 * k) - jump, 2e-3 * std::sin(0.007 * k));
    for (double& v : y) v += noise(rng);
    path.push_back(std::move(y));
  }
  for (const char* extra : {"", "iterations: 3\n", "noise_std_v: [1e-3, 2e-3, 1.5e-3, 1e-3]\nbackoff: 0.5\n"}) {
    SCOPED_TRACE(extra);
    Rig sized(std::string("model: hall\n") + extra, hall_model("hall", "[1, 5]"));
    Rig generic(std::string("model: hall\ncompile_time_sizes: false\n") + extra, hall_model("hall", "[1, 5]"));
    ASSERT_TRUE(sized.ok() && generic.ok());
    EXPECT_TRUE(sized.block().fixed_size());
    EXPECT_FALSE(generic.block().fixed_size());
    std::size_t allocations = 0;
    for (std::size_t k = 0; k < path.size(); ++k) {
      if (k == 350) {
        const double warm_start[3] = {0.002, -0.001, 0.001};
        const std::uint8_t present[3] = {1, 1, 1};
        sized.estimator().import_state(warm_start, nullptr, present);
        generic.estimator().import_state(warm_start, nullptr, present);
      }
      auto in = sized.harness().input("measurement");  // the port lookup allocates its name
      std::copy(path[k].begin(), path[k].end(), in.begin());
      allocations += estimator_testing::allocations_during([&] { ASSERT_EQ(sized.harness().step(), StepStatus::ok); });
      ASSERT_EQ(generic.step(path[k]), StepStatus::ok);
      ASSERT_TRUE(same_outputs(sized, generic)) << "tick " << k;
    }
    EXPECT_EQ(sized.block().backoffs(), generic.block().backoffs());
    EXPECT_GT(sized.block().backoffs(), 0u) << "the jumps must exercise the back-off";
    EXPECT_EQ(allocations, 0u) << "the sized step() allocated";
  }
}

TEST(GlsdcSized, SingularTicksMatchTheGenericPath) {
  // The field-extremum geometry of SingularNormalMatrixHoldsTheEstimate: the kept (singular)
  // factorisation must skip the same ticks as the generic path, which factors again each time.
  const std::string& models = kFieldExtremumModels;
  Rig sized(params_with_initial(kQuarterPitch, kQuarterPitch, 0.0), models);
  Rig generic(params_with_initial(kQuarterPitch, kQuarterPitch, 0.0, "compile_time_sizes: false\n"), models);
  ASSERT_TRUE(sized.ok() && generic.ok());
  ASSERT_TRUE(sized.block().fixed_size());
  std::vector<double> y(4);
  for (int k = 0; k < 20; ++k) {
    const double offset = k < 10 ? 0.001 : 0.001 * (k - 9);
    const double state[3] = {kQuarterPitch + offset, kQuarterPitch - offset, 1e-4 * k};
    sized.model().evaluate(state, y.data());
    ASSERT_EQ(sized.step(y), StepStatus::ok);
    ASSERT_EQ(generic.step(y), StepStatus::ok);
    ASSERT_TRUE(same_outputs(sized, generic)) << "tick " << k;
  }
  EXPECT_GT(sized.block().singular_skips(), 0u);
  EXPECT_EQ(sized.block().singular_skips(), generic.block().singular_skips());
}

}  // namespace
}  // namespace lode::plugins
