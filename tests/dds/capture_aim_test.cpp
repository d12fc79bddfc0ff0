// The publisher's aim (core/dds/src/capture_aim.hpp): awake before the usual capture,
// polling for a bounded time, asleep past the late ones.
#include "capture_aim.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <random>

namespace {

using lode::dds::bridge_detail::CaptureAim;
using lode::dds::bridge_detail::QuantileTracker;
using namespace std::chrono;

std::int64_t ns(steady_clock::time_point t) { return duration_cast<nanoseconds>(t.time_since_epoch()).count(); }

TEST(QuantileTracker, SettlesAtTheQuantileItsStepsSayFromAnyStart) {
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::int64_t> us(0, 999);  // uniform: quantile q is q * 1000 us
  QuantileTracker p10(100, 900), p90(1000, 111);
  p10.add(900'000);  // a first value far from where it settles
  p90.add(50'000);
  for (int i = 0; i < 200'000; ++i) {
    const std::int64_t v = us(rng) * 1000;
    p10.add(v);
    p90.add(v);
  }
  EXPECT_NEAR(static_cast<double>(p10.value_ns()), 100'000.0, 20'000.0);
  EXPECT_NEAR(static_cast<double>(p90.value_ns()), 900'000.0, 20'000.0);
}

TEST(CaptureAim, WakesBeforeTheEarlyCapturesLessTheTimersLatenessAndSleepsPastTheLateOnes) {
  constexpr std::int64_t kStep = 1'000'000;  // 1 kHz
  constexpr std::int64_t kStart = 5'000'000'000;  // the run's start on CLOCK_MONOTONIC
  CaptureAim aim;
  aim.set_step_ns(kStep);
  EXPECT_FALSE(aim.next()) << "no capture seen: nothing to aim at";
  std::mt19937_64 rng(3);
  // Captures 20..120 us after the scheduled time; the timer fires 30 us late.
  std::uniform_int_distribution<std::int64_t> delay_us(20, 120);
  std::int64_t stamp = 0;
  for (int i = 0; i < 20'000; ++i, stamp += kStep) {
    aim.learn_capture(stamp, kStart + stamp + delay_us(rng) * 1000);
    aim.learn_oversleep(microseconds(30));
  }
  const auto next = aim.next();
  ASSERT_TRUE(next);
  const std::int64_t scheduled = kStart + stamp;  // the cycle after the last one learnt
  // The 10th percentile of the delay is 30 us; less 30 us of timer lateness: about on time.
  EXPECT_NEAR(static_cast<double>(ns(next->wake) - scheduled), 0.0, 5'000.0);
  // The 98th percentile: 118 us.
  EXPECT_NEAR(static_cast<double>(ns(next->late) - scheduled), 118'000.0, 5'000.0);
  // Later than that it keeps looking until the cycle after is usually captured (its 10th
  // percentile, 30 us), then sleeps on the doorbell.
  EXPECT_NEAR(static_cast<double>(ns(next->next_cycle) - scheduled), kStep + 30'000.0, 5'000.0);
  EXPECT_EQ(aim.spin_budget(), nanoseconds(50'000)) << "1/20 of 1 ms";
}

TEST(CaptureAim, PollsAtMostOneTwentiethOfThePeriod) {
  CaptureAim aim;
  aim.set_step_ns(100'000);  // 10 kHz
  EXPECT_EQ(aim.spin_budget(), nanoseconds(5'000));
  aim.set_step_ns(100'000'000);  // 10 Hz: never more than 50 us
  EXPECT_EQ(aim.spin_budget(), nanoseconds(50'000));
}

}  // namespace
