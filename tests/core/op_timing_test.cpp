// Each op's execution time is its own: the pipeline reads the clock once per timed op and
// takes the previous op's end as the next op's start, so a slow op must not leak into the
// statistics of the op after it.
#include <gtest/gtest.h>

#include <cstdint>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/diagnostics.hpp"

namespace {

TEST(OpTiming, ASlowOpIsChargedToItselfNotToTheNextOne) {
  lode::PluginRegistry registry;
  ASSERT_TRUE(registry.load_file(LODE_BAD_PLUGIN_DIR "/lode-test.overruns_at.so"));
  // Blocks without inputs run in the order written: the slow one, then the quick one.
  const char* text = R"(pipeline: op_timing
rate_hz: 100
blocks:
  slow: { plugin: test.overruns_at, cycles: [0, 1, 2, 3, 4], busy_us: 3000 }
  quick: { plugin: test.overruns_at, cycles: [1000000] }
)";
  lode::Diagnostics diag;
  auto pipeline = lode::Pipeline::load_text(text, "op_timing", registry, diag);
  ASSERT_TRUE(pipeline) << diag.format();
  ASSERT_TRUE(pipeline->activate());
  ASSERT_EQ(pipeline->ops().size(), 2u);
  ASSERT_EQ(pipeline->ops()[0].label, "slow");
  lode::Tick tick;
  tick.dt_s = 0.01;
  for (std::uint64_t k = 0; k < 5; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * 10'000'000;
    ASSERT_EQ(pipeline->run_cycle(tick, /*time_ops=*/true).status, lode::StepStatus::ok);
  }
  const auto& slow = *pipeline->ops()[0].exec_time;
  const auto& quick = *pipeline->ops()[1].exec_time;
  EXPECT_GE(slow.percentile(0.5), 3'000'000) << "the slow op's 3 ms busy wait is not in its own time";
  // Its step returns at once: well under a millisecond even on a loaded host.
  EXPECT_LT(quick.percentile(0.5), 1'000'000) << "the quick op was charged with the slow one's time";
}

}  // namespace
