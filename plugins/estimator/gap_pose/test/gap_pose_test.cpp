// estimator.gap_pose: inverts sensor.capacitive_gap on a simulated rigid body (io.sim with
// plant.rigid_body6) to rounding at poses far beyond the experiments, follows a moving body, turns
// white gap noise into the pose noise (H'WH)^-1 predicts, and refuses a probe layout that cannot
// see all six degrees of freedom.
#include "gap_pose.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "estimator/testing/harness_setup.hpp"
#include "estimator/testing/yaml_numbers.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace {

using lode::estimator_testing::exact;
using lode::estimator_testing::exact_list;
using lode::estimator_testing::started;

constexpr double kRateHz = 2500.0;

std::string pipeline_yaml(const std::array<double, 6>& pose, const std::array<double, 6>& velocity, double noise_v,
                          int iterations) {
  return "pipeline: gap_pose_test\nrate_hz: 2500\n"
         "models:\n"
         "  stage: {plugin: plant.rigid_body6, initial: " + exact_list(pose) + ", initial_velocity: " + exact_list(velocity) +
         "}\n"
         "  gaps: {plugin: sensor.capacitive_gap}\n"
         "blocks:\n"
         "  board: {plugin: io.sim, plant: stage, sensors: [gaps], noise_std_v: " + exact(noise_v) +
         ", adc_bits: 0, seed: 3, inputs: {command: feed.force}}\n"
         "  solver: {plugin: estimator.gap_pose, model: gaps, noise_std_v: 1.2e-3, iterations: " +
         std::to_string(iterations) + ", inputs: {measurement: board.signals}}\n";
}

struct Chain {
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  std::unique_ptr<lode::Pipeline> pipeline;
  std::uint64_t cycle = 0;

  explicit Chain(const std::string& yaml) {
    pipeline = lode::Pipeline::load_text(
        yaml, "gap_pose_test.yaml", registry, diagnostics,
        {{"force", {{"fx", "N"}, {"fy", "N"}, {"fz", "N"}, {"tx", "N*m"}, {"ty", "N*m"}, {"tz", "N*m"}}}});
  }
  bool run_cycle() {
    lode::Tick tick;
    tick.cycle = cycle;
    tick.dt_s = 1.0 / kRateHz;
    tick.time_ns = static_cast<std::int64_t>(cycle) * 400000;
    ++cycle;
    return pipeline->run_cycle(tick, false).status == lode::StepStatus::ok;
  }
  const double* signal(const std::string& name) const { return pipeline->signal(name)->data; }
};

TEST(GapPose, RecoversLargePosesToRounding) {
  LODE_REQUIRE_PLUGINS("io.sim", "plant.rigid_body6", "sensor.capacitive_gap");
  const std::array<std::array<double, 6>, 4> poses{{
      {1e-6, -5e-7, 2.5e-7, 1e-6, 4e-6, -2e-6},         // the experiments' scale
      {4e-4, -3e-4, 2e-4, 0.01, -0.008, 0.02},          // +-0.4 mm, 20 mrad
      {-4.5e-4, 4.5e-4, -4e-4, -0.005, 0.005, -0.005},  // near the end of the 500-1500 um range
      {0, 0, 0, 0, 0, 0},
  }};
  for (const auto& pose : poses) {
    Chain chain(pipeline_yaml(pose, {}, 0.0, 3));
    ASSERT_TRUE(chain.pipeline) << chain.diagnostics.format();
    ASSERT_TRUE(chain.pipeline->activate());
    ASSERT_TRUE(chain.run_cycle());  // the first tick starts from zero: 3 Newton steps
    const double* estimate = chain.signal("solver.pose");
    for (std::size_t i = 0; i < 6; ++i) {
      EXPECT_NEAR(estimate[i], pose[i], i < 3 ? 1e-15 : 1e-13) << "state " << i << " pose " << pose[1];
    }
    EXPECT_LT(chain.signal("solver.cost")[0], 1e-12);
  }
}

TEST(GapPose, FollowsAMovingBodyWithOneStepPerTick) {
  LODE_REQUIRE_PLUGINS("io.sim", "plant.rigid_body6", "sensor.capacitive_gap");
  // 11.5 um/s and 200 urad/s (rates like the reciprocating move of Gutierrez & Li's Fig. 9): the
  // warm start is one period behind; one Newton step leaves ~(motion per tick)^2 = (8e-8)^2.
  Chain chain(pipeline_yaml({}, {11.5e-6, -5e-6, 2e-6, 1e-4, -1e-4, 2e-4}, 0.0, 1));
  ASSERT_TRUE(chain.pipeline) << chain.diagnostics.format();
  ASSERT_TRUE(chain.pipeline->activate());
  double worst = 0.0;
  for (int k = 0; k < 500; ++k) {
    ASSERT_TRUE(chain.run_cycle());
    const double* truth = chain.signal("board.truth");
    const double* estimate = chain.signal("solver.pose");
    for (std::size_t i = 0; i < 6; ++i) worst = std::max(worst, std::abs(estimate[i] - truth[i]));
  }
  std::printf("moving body, 1 Gauss-Newton step per tick: worst pose error %.3g\n", worst);
  EXPECT_LT(worst, 1e-13);
}

TEST(GapPose, PoseNoiseMatchesTheGeometry) {
  LODE_REQUIRE_PLUGINS("io.sim", "plant.rigid_body6", "sensor.capacitive_gap");
  // 1.2 mV at 20 mV/um is the paper's 60 nm rms per probe.
  Chain chain(pipeline_yaml({}, {}, 1.2e-3, 2));
  ASSERT_TRUE(chain.pipeline) << chain.diagnostics.format();
  ASSERT_TRUE(chain.pipeline->activate());
  const lode::Json described = chain.pipeline->describe();
  const lode::Json* block = described.find("blocks")->find("solver")->find("derived");
  ASSERT_NE(block, nullptr) << described.dump();
  const auto& predicted = block->find("pose_noise_std_at_home")->elements();
  ASSERT_EQ(predicted.size(), 6u);
  constexpr int kSamples = 20000;
  std::array<double, 6> sum{}, sum_sq{};
  for (int k = 0; k < kSamples; ++k) {
    ASSERT_TRUE(chain.run_cycle());
    const double* estimate = chain.signal("solver.pose");
    for (std::size_t i = 0; i < 6; ++i) {
      sum[i] += estimate[i];
      sum_sq[i] += estimate[i] * estimate[i];
    }
  }
  for (std::size_t i = 0; i < 6; ++i) {
    const double mean = sum[i] / kSamples;
    const double std_dev = std::sqrt(sum_sq[i] / kSamples - mean * mean);
    std::printf("pose noise %zu: measured %.4g, (H'WH)^-1 predicts %.4g\n", i, std_dev, predicted[i].as_number());
    EXPECT_NEAR(std_dev / predicted[i].as_number(), 1.0, 0.03) << i;
  }
  // Translations are the probes' 60 nm (one probe per direction at most), angles ~ 60 nm / lever.
  EXPECT_NEAR(predicted[1].as_number(), 60e-9, 1e-12);  // y: one probe
  EXPECT_GT(predicted[3].as_number(), 0.5e-6);          // roll: urad scale
  EXPECT_LT(predicted[3].as_number(), 3e-6);
}

TEST(GapPose, RefusesProbesThatCannotSeeAllSixDof) {
  LODE_REQUIRE_PLUGINS("sensor.capacitive_gap");
  lode::testing::BlockHarness h("estimator.gap_pose", "model: gaps\n", kRateHz,
                                "gaps:\n"
                                "  plugin: sensor.capacitive_gap\n"
                                "  probes:\n"  // six probes, all vertical: x, y and yaw are invisible
                                "    - {name: a, target_m: [0.05, 0, 0], axis: [0, 0, 1]}\n"
                                "    - {name: b, target_m: [-0.05, 0, 0], axis: [0, 0, 1]}\n"
                                "    - {name: c, target_m: [0, 0.05, 0], axis: [0, 0, 1]}\n"
                                "    - {name: d, target_m: [0, -0.05, 0], axis: [0, 0, 1]}\n"
                                "    - {name: e, target_m: [0.03, 0.03, 0], axis: [0, 0, 1]}\n"
                                "    - {name: f, target_m: [-0.03, 0.03, 0], axis: [0, 0, 1]}\n");
  h.feed("measurement", {{"a", "V"}, {"b", "V"}, {"c", "V"}, {"d", "V"}, {"e", "V"}, {"f", "V"}});
  EXPECT_FALSE(h.configure());
  EXPECT_NE(h.diagnostics().find("cannot resolve all six"), std::string::npos) << h.diagnostics();
}

TEST(GapPose, InvalidParametersAreReportedAtOnce) {
  LODE_REQUIRE_PLUGINS("sensor.capacitive_gap");
  lode::testing::BlockHarness h("estimator.gap_pose", "model: gaps\niterations: 0\nnoise_std_v: [1, 2]\n", kRateHz,
                                "gaps: {plugin: sensor.capacitive_gap}\n");
  h.feed("measurement", {{"z1", "V"}, {"z2", "V"}, {"z3", "V"}, {"x1", "V"}, {"x2", "V"}, {"y1", "V"}});
  EXPECT_FALSE(h.configure());
  const std::string d = h.diagnostics();
  EXPECT_NE(d.find("iterations"), std::string::npos) << d;
  EXPECT_NE(d.find("noise_std_v"), std::string::npos) << d;
}

TEST(GapPose, NoAllocationInStep) {
  LODE_REQUIRE_PLUGINS("sensor.capacitive_gap");
  lode::testing::BlockHarness h("estimator.gap_pose", "model: gaps\n", kRateHz, "gaps: {plugin: sensor.capacitive_gap}\n");
  h.feed("measurement", {{"z1", "V"}, {"z2", "V"}, {"z3", "V"}, {"x1", "V"}, {"x2", "V"}, {"y1", "V"}});
  ASSERT_TRUE(started(h));
  LODE_REQUIRE_ALLOCATION_COUNTING();
  auto in = h.input("measurement");
  const std::size_t before = lode::testing::allocation_count();
  for (int k = 0; k < 10000; ++k) {
    for (std::size_t i = 0; i < 6; ++i) in[i] = 1e-3 * std::sin(0.01 * k + static_cast<double>(i));
    if (h.step() != lode::StepStatus::ok) FAIL() << "step faulted: " << h.block().fault_reason();
  }
  EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
}

}  // namespace
