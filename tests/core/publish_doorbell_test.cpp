// The RT thread's doorbell to the telemetry publisher (PublishDoorbell, TelemetryTap's
// cycle_finished): a sleeping waiter is woken by a ring, an awake one costs the ringer no
// system call, no ring is lost between the waiter's check and its sleep, and only cycles
// that put a record into a ring ring it.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "lode/telemetry.hpp"

namespace {

using namespace std::chrono_literals;

TEST(PublishDoorbell, WaitTimesOutWithoutARing) {
  lode::PublishDoorbell doorbell;
  EXPECT_FALSE(doorbell.wait(doorbell.sequence(), 20ms));
  EXPECT_FALSE(doorbell.wait(doorbell.sequence(), 0ns)) << "no time left: no wait";
  EXPECT_EQ(doorbell.wakes(), 0u);
}

TEST(PublishDoorbell, ARingWakesASleepingWaiterLongBeforeItsTimeout) {
  lode::PublishDoorbell doorbell;
  const std::uint32_t first_seen = doorbell.sequence();
  std::atomic<bool> woken{false};
  std::atomic<bool> returned{false};
  std::atomic<bool> give_up{false};
  std::thread waiter([&] {
    // A ring that lands before the waiter is asleep moves the sequence and wait() returns at
    // once without sleeping (as it must); on a loaded host the thread may start that late.
    // Then wait again, so that some ring has to find this thread asleep and wake it.
    std::uint32_t seen = first_seen;
    bool rung = false;
    do {
      rung = doorbell.wait(seen, 60s);
      seen = doorbell.sequence();
    } while (doorbell.wakes() == 0 && !give_up);
    woken = rung;
    returned = true;
  });
  // Ring once a millisecond until the waiter is through: it goes on waiting until some ring
  // has had to make the wake-up system call, i.e. found it asleep.
  for (int i = 0; i < 5000 && !returned; ++i) {
    std::this_thread::sleep_for(1ms);
    doorbell.ring();
  }
  const bool woken_by_ring = returned;
  give_up = true;
  doorbell.wake_all();  // whatever happened, end the wait so the thread can be joined
  waiter.join();
  ASSERT_GE(doorbell.wakes(), 1u) << "5000 rings, one a millisecond, and none found the waiter asleep";
  ASSERT_TRUE(woken_by_ring) << "the waiter still slept after 5 s of rings: ring() did not wake it (its timeout "
                                "is 60 s)";
  EXPECT_TRUE(woken) << "wait() reported a timeout, but it was rung";
  EXPECT_NE(doorbell.sequence(), first_seen);
  // What the wake-ups cost the ringer is measured: a system call takes far more than 0 ns
  // and, on any host, less than the 5 s this test may take.
  EXPECT_GT(doorbell.wake_ns(), 0u) << doorbell.wakes() << " wake-ups, none of them timed";
  EXPECT_LT(doorbell.wake_ns(), 5'000'000'000u);
}

TEST(PublishDoorbell, AnAwakeConsumerCostsTheRingerNoSystemCall) {
  lode::PublishDoorbell doorbell;
  for (int i = 0; i < 1000; ++i) doorbell.ring();
  EXPECT_EQ(doorbell.sequence(), 1000u);
  EXPECT_EQ(doorbell.wakes(), 0u) << "nobody waited, yet ring() made system calls";
  EXPECT_EQ(doorbell.wake_ns(), 0u) << "no system call, yet time was counted for one";
  EXPECT_TRUE(doorbell.wait(0, 10s)) << "the sequence moved on: wait() must return at once";
}

TEST(PublishDoorbell, NoRingIsLostBetweenTheWaitersCheckAndItsSleep) {
  // A producer rings at random moments; the consumer waits for each new sequence with a long
  // timeout. A lost wake-up would leave it asleep for the whole timeout.
  lode::PublishDoorbell doorbell;
  constexpr std::uint32_t kRings = 20000;
  std::atomic<bool> stalled{false};
  std::thread consumer([&] {
    std::uint32_t seen = 0;
    while (seen != kRings) {
      const auto before = std::chrono::steady_clock::now();
      doorbell.wait(seen, 30s);
      if (std::chrono::steady_clock::now() - before > 20s) stalled = true;
      seen = doorbell.sequence();
    }
  });
  for (std::uint32_t i = 0; i < kRings; ++i) {
    if (i % 64 == 0) std::this_thread::yield();
    doorbell.ring();
  }
  consumer.join();
  EXPECT_FALSE(stalled) << "a ring was lost: the consumer slept through its timeout";
}

TEST(PublishDoorbell, WakeAllEndsAWaitWithoutARing) {
  lode::PublishDoorbell doorbell;
  std::atomic<bool> returned{false};
  std::thread waiter([&] {
    doorbell.wait(doorbell.sequence(), 60s);
    returned = true;
  });
  for (int i = 0; i < 5000 && !returned; ++i) {
    std::this_thread::sleep_for(1ms);
    doorbell.wake_all();
  }
  EXPECT_TRUE(returned) << "wake_all() did not end the wait";
  waiter.join();
}

TEST(TelemetryTap, RingsTheDoorbellOnlyForCyclesThatPublish) {
  static const lode::Elements kElements = {{"x", "m"}};
  std::vector<double> value(1, 1.0);
  lode::TelemetrySpec spec;
  spec.signals.push_back({lode::SignalRef{"b", "out", value.data(), &kElements}, 4, ""});
  lode::TelemetryTap tap(spec, 1000.0);
  lode::Tick tick;
  for (std::uint64_t k = 0; k < 40; ++k) {
    tick.cycle = k;
    tap.after_cycle(tick);
    tap.cycle_finished();
  }
  EXPECT_EQ(tap.offered(), 10u);
  EXPECT_EQ(tap.doorbell().sequence(), 10u) << "one ring per cycle that put a record into a ring (every 4th)";
  tap.cycle_finished();
  EXPECT_EQ(tap.doorbell().sequence(), 10u) << "a second cycle_finished() without a new record rang again";
}

}  // namespace
