// run_cycle has two ways through the ops: the bare loop (nothing timed, no family watched:
// each op is just its call) and the watched one (op timing, health monitor, shadows, a hot
// swap's warming candidate). The pipeline keeps one flag that says which applies, and a hot
// swap changes it on the RT thread. These tests check that the two ways give the same
// outputs, and that a candidate warming beside a primary nobody else watches is run.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "config_text.hpp"
#include "lode/hot_swap.hpp"
#include "lode/pipeline.hpp"
#include "lode/sdk/tunables.hpp"
#include "swap_rig.hpp"

namespace {

using lode::test::read_config;

lode::Tick tick_of(const lode::Pipeline& p, std::uint64_t cycle) {
  lode::Tick t;
  t.cycle = cycle;
  t.time_ns = static_cast<std::int64_t>(cycle) * p.period_ns();
  t.dt_s = 1.0 / p.rate_hz();
  return t;
}

TEST(BareCycle, GivesTheOutputsOfTheTimedCycleBitForBit) {
  // kawato_planar has no shadows and no health monitor: without op timing every cycle takes
  // the bare loop, with it every cycle the watched one. 3 s (the steps at 1 s and 2 s).
  lode::test::SwapRig bare(read_config("kawato_planar.yaml"), "kawato_planar.yaml (bare)");
  lode::test::SwapRig timed(read_config("kawato_planar.yaml"), "kawato_planar.yaml (timed)");
  ASSERT_TRUE(bare.pipeline && timed.pipeline) << bare.diagnostics.format() << timed.diagnostics.format();
  ASSERT_TRUE(bare.activated && timed.activated);
  const auto a = bare.pipeline->signals();
  const auto b = timed.pipeline->signals();
  ASSERT_EQ(a.size(), b.size());
  for (std::uint64_t k = 0; k < 2400; ++k) {
    ASSERT_EQ(bare.pipeline->run_cycle(tick_of(*bare.pipeline, k), false).status, lode::StepStatus::ok) << k;
    ASSERT_EQ(timed.pipeline->run_cycle(tick_of(*timed.pipeline, k), true).status, lode::StepStatus::ok) << k;
    for (std::size_t s = 0; s < a.size(); ++s)
      ASSERT_EQ(std::memcmp(a[s].data, b[s].data, a[s].size() * sizeof(double)), 0)
          << "cycle " << k << ": " << a[s].name() << " differs";
  }
}

TEST(BareCycle, AFaultStopsTheCycleAtTheSameOpEitherWay) {
  // A NaN channel from the simulated board (its live fault injection) from cycle 10: both
  // ways fault on the same cycle, at the same op, and leave the same outputs behind (the ops
  // after the faulting one not run).
  lode::test::SwapRig bare(read_config("kawato_planar.yaml"), "kawato_planar.yaml (bare)");
  lode::test::SwapRig timed(read_config("kawato_planar.yaml"), "kawato_planar.yaml (timed)");
  ASSERT_TRUE(bare.pipeline && timed.pipeline && bare.activated && timed.activated);
  const auto a = bare.pipeline->signals();
  const auto b = timed.pipeline->signals();
  for (std::uint64_t k = 0; k < 100; ++k) {
    if (k == 10) {
      for (auto* rig : {&bare, &timed}) {
        auto* board = dynamic_cast<lode::Tunables*>(rig->pipeline->block("stage"));
        ASSERT_NE(board, nullptr);
        const char* why = nullptr;
        ASSERT_TRUE(board->set_tunable(0, 1.0, why)) << why;  // inject_nan_channel 1
      }
    }
    const auto ra = bare.pipeline->run_cycle(tick_of(*bare.pipeline, k), false);
    const auto rb = timed.pipeline->run_cycle(tick_of(*timed.pipeline, k), true);
    ASSERT_EQ(ra.status, rb.status) << "cycle " << k;
    ASSERT_EQ(ra.failed_op, rb.failed_op) << "cycle " << k;
    ASSERT_EQ(ra.envelope, rb.envelope) << "cycle " << k;
    for (std::size_t s = 0; s < a.size(); ++s)
      ASSERT_EQ(std::memcmp(a[s].data, b[s].data, a[s].size() * sizeof(double)), 0)
          << "cycle " << k << ": " << a[s].name() << " differs";
    if (ra.status != lode::StepStatus::ok) {
      EXPECT_GE(k, 10u);
      return;
    }
  }
  FAIL() << "a NaN channel from cycle 10 on never faulted the cycle";
}

TEST(BareCycle, ACandidateWarmingBesideAnUnwatchedPrimaryIsStepped) {
  // A swap of kf with 20 cycles as a shadow first: the candidate must be stepped on each of
  // them (it takes over once they have run), although no family of kawato_planar is watched
  // and the cycle runs without op timing, on the bare loop until the swap begins.
  lode::test::SwapRig rig(read_config("kawato_planar.yaml"), "kawato_planar.yaml");
  ASSERT_TRUE(rig.pipeline && rig.activated) << rig.diagnostics.format();
  const auto cycle = [&rig] {
    const lode::Tick t = tick_of(*rig.pipeline, rig.cycle++);
    rig.swapper->before_cycle(t);
    const auto r = rig.pipeline->run_cycle(t, false);
    rig.swapper->after_cycle(t);
    return r.status;
  };
  for (int i = 0; i < 100; ++i) ASSERT_EQ(cycle(), lode::StepStatus::ok);
  lode::SwapRequest req;
  req.block = "kf";
  req.plugin = "estimator.kalman";
  req.params =
      "{motion: constant_acceleration, q: [1.0e2, 1.0e2, 1.0e5], p0: 1.0e-8, r: [2.2e-10, 2.2e-10, 9.6e-9], "
      "output: predicted}";
  req.shadow_cycles = 20;
  auto prepared = rig.swapper->prepare(req);
  ASSERT_TRUE(prepared) << prepared.error();
  rig.swapper->post(**prepared);
  int cycles = 0;
  while (!rig.swapper->done() && cycles < 1000) {
    ASSERT_EQ(cycle(), lode::StepStatus::ok);
    ++cycles;
  }
  ASSERT_TRUE(rig.swapper->done()) << "the warming candidate never finished its 20 cycles as a shadow";
  const auto report = rig.swapper->finish(std::move(*prepared));
  ASSERT_TRUE(report.ok) << report.message;
  // Posted, prefetched (1 cycle), exchanged at its end, 20 cycles warming, installed, kept.
  EXPECT_LE(cycles, 25);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(cycle(), lode::StepStatus::ok);
}

}  // namespace
