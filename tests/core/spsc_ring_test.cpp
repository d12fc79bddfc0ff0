// The one SPSC ring (lode/spsc_ring.hpp) and what is built on it: order, wrap-around, drops
// counted when full and never blocking, and a producer and a consumer thread that agree on
// every value (run under ThreadSanitizer by tests/tsan/run.sh).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "lode/sample_ring.hpp"
#include "lode/spsc_ring.hpp"

namespace {

TEST(SpscQueue, KeepsOrderAcrossWrapAroundAndCountsDrops) {
  lode::SpscQueue<int> q(5);  // rounded up to 8
  int out = 0;
  EXPECT_FALSE(q.pop(out));
  for (int lap = 0; lap < 3; ++lap) {
    for (int i = 0; i < 8; ++i) EXPECT_TRUE(q.push(lap * 100 + i));
    EXPECT_FALSE(q.push(-1)) << "a full ring refuses";
    for (int i = 0; i < 8; ++i) {
      ASSERT_TRUE(q.pop(out));
      EXPECT_EQ(out, lap * 100 + i);
    }
    EXPECT_FALSE(q.pop(out));
  }
  EXPECT_EQ(q.dropped(), 3u);
}

TEST(SpscQueue, AProducerAndAConsumerThreadAgreeOnEveryValue) {
  constexpr std::uint64_t kValues = 200000;
  lode::SpscQueue<std::uint64_t> q(64);
  std::uint64_t attempts = 0;
  std::atomic<bool> stop{false};
  std::thread producer([&] {
    for (std::uint64_t v = 0; v < kValues && !stop.load(); ++attempts)
      if (q.push(v)) ++v;  // a refused value is retried, so every one arrives
  });
  std::uint64_t expected = 0, v = 0, wrong = 0;
  while (expected < kValues && wrong == 0) {
    if (!q.pop(v)) continue;
    if (v != expected) ++wrong;
    ++expected;
  }
  stop.store(true);
  producer.join();
  EXPECT_EQ(wrong, 0u) << "value " << v << " arrived where " << expected - 1 << " was due";
  EXPECT_EQ(q.dropped(), attempts - kValues) << "every refused push is counted, and only those";
}

TEST(SampleRing, ClaimAndPublishGatherARecord) {
  lode::SampleRing ring(3, 2);
  double* v = ring.claim();
  ASSERT_NE(v, nullptr);
  v[0] = 1.0;
  v[1] = 2.0;
  v[2] = 3.0;
  lode::SampleHeader h;
  h.cycle = 7;
  h.stamp_ns = -5;
  ring.publish(h);
  const double three[3] = {4.0, 5.0, 6.0};
  EXPECT_TRUE(ring.push(h, three));
  EXPECT_EQ(ring.claim(), nullptr) << "two records fill a 2-record ring";
  EXPECT_EQ(ring.dropped(), 1u);
  lode::SampleHeader got;
  const double* r = ring.front(got);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(got.cycle, 7u);
  EXPECT_EQ(got.stamp_ns, -5);
  EXPECT_EQ(r[2], 3.0);
  ring.pop();
  r = ring.front(got);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r[0], 4.0);
}

}  // namespace
