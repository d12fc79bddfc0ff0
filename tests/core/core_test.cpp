// Core mechanisms: units, histograms, rings, parameter diagnostics, JSON.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <thread>

#include "lode/sdk/histogram.hpp"
#include "lode/sdk/json.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/rt_log.hpp"
#include "lode/scheduler.hpp"
#include "lode/sdk/units.hpp"
#include "../../core/src/params_node.hpp"

namespace {

TEST(Units, CanonicalSpellingsCompare) {
  EXPECT_TRUE(lode::units_compatible("N*m", "N.m"));
  EXPECT_TRUE(lode::units_compatible("N m", "N*m"));
  EXPECT_TRUE(lode::units_compatible("rad/s^2", "rad/s2"));
  EXPECT_TRUE(lode::units_compatible("", "1"));
  EXPECT_TRUE(lode::units_compatible("V", "*"));
  EXPECT_FALSE(lode::units_compatible("m", "rad"));
  EXPECT_FALSE(lode::units_compatible("N", "N*m"));
}

TEST(Histogram, PercentilesWithinBinResolution) {
  lode::Histogram h;
  std::mt19937_64 rng(3);
  std::vector<std::int64_t> values;
  std::uniform_int_distribution<std::int64_t> d(1000, 2'000'000);
  for (int i = 0; i < 20000; ++i) {
    values.push_back(d(rng));
    h.record(values.back());
  }
  std::sort(values.begin(), values.end());
  for (double q : {0.5, 0.9, 0.99}) {
    const double exact = static_cast<double>(values[static_cast<std::size_t>(q * (values.size() - 1))]);
    EXPECT_NEAR(static_cast<double>(h.percentile(q)), exact, exact * 0.04) << q;
  }
  EXPECT_EQ(h.max(), values.back());
  EXPECT_EQ(h.min(), values.front());
  EXPECT_EQ(h.count(), 20000u);
}

TEST(Histogram, BinEdgesAreMonotonicAndContainValues) {
  for (std::int64_t v : {0LL, 1LL, 31LL, 32LL, 33LL, 1000LL, 123456789LL, 40'000'000'000LL}) {
    const int b = lode::Histogram::bin_of(v);
    EXPECT_LE(v, lode::Histogram::upper_edge(b)) << v;
    if (b > 0) {
      EXPECT_GT(v, lode::Histogram::upper_edge(b - 1) - 1) << v;
    }
  }
}

TEST(RtLogRing, DropsAndCountsWhenFullNeverBlocks) {
  lode::RtLogRing ring;
  lode::LogRecord r;
  r.format = "x {}";
  std::size_t pushed = 0;
  for (std::size_t i = 0; i < lode::RtLogRing::kCapacity + 10; ++i) pushed += ring.push(r) ? 1 : 0;
  EXPECT_EQ(pushed, lode::RtLogRing::kCapacity);
  EXPECT_EQ(ring.dropped(), 10u);
  lode::LogRecord out;
  std::size_t popped = 0;
  while (ring.pop(out)) ++popped;
  EXPECT_EQ(popped, lode::RtLogRing::kCapacity);
}

TEST(RtLogRing, ConcurrentProducersLoseNothingBelowCapacity) {
  lode::RtLogRing ring;
  std::vector<std::thread> producers;
  for (int t = 0; t < 4; ++t)
    producers.emplace_back([&, t] {
      for (int i = 0; i < 500; ++i) {
        lode::LogRecord r;
        r.args[0] = t;
        r.args[1] = i;
        ring.push(r);
      }
    });
  for (auto& p : producers) p.join();
  lode::LogRecord out;
  std::array<int, 4> next{};
  std::size_t n = 0;
  while (ring.pop(out)) {
    const auto t = static_cast<std::size_t>(out.args[0]);
    EXPECT_EQ(static_cast<int>(out.args[1]), next[t]++);  // per-producer order kept
    ++n;
  }
  EXPECT_EQ(n, 2000u);
  EXPECT_EQ(ring.dropped(), 0u);
}

TEST(SignalTap, CountsDropsWhenConsumerStalls) {
  std::vector<double> values = {1.0, 2.0};
  lode::Elements e = {{"a", "m"}, {"b", "m"}};
  lode::SignalRef ref{"blk", "out", values.data(), &e};
  lode::SignalTap tap({ref}, 8);
  for (int k = 0; k < 10; ++k) {
    values[0] = k;
    tap.capture(static_cast<std::uint64_t>(k), k * 1000);
  }
  EXPECT_EQ(tap.dropped(), 2u);
  std::vector<double> rows;
  EXPECT_EQ(tap.drain(rows), 8u);
  ASSERT_EQ(rows.size(), 8u * tap.stride());
  EXPECT_EQ(rows[0], 0.0);                     // cycle 0 first
  EXPECT_EQ(rows[7 * tap.stride() + 2], 7.0);  // value of cycle 7 last
}


// A tap copies signals that lie next to each other in one piece: what each record holds must
// still be every signal in the order given, wherever they lie (adjacent, apart, in an order
// other than their storage's, empty).
TEST(SignalTap, RecordsSignalsInTheirOrderWhereverTheyLie) {
  std::vector<double> storage(10);
  for (std::size_t i = 0; i < storage.size(); ++i) storage[i] = 100.0 + static_cast<double>(i);
  lode::Elements two = {{"a", ""}, {"b", ""}}, one = {{"a", ""}}, none;
  const double* at = storage.data();
  // [0, 2) and [2, 4) adjacent; [7, 8) apart; [4, 6) adjacent to [2, 4) in storage but listed
  // after [7, 8); an empty signal between; [8, 10) after [4, 6) with a gap of two.
  const std::vector<lode::SignalRef> signals = {
      {"s0", "o", at + 0, &two}, {"s1", "o", at + 2, &two}, {"s2", "o", at + 7, &one},
      {"s3", "o", at + 8, &none}, {"s4", "o", at + 4, &two}, {"s5", "o", at + 8, &two}};
  lode::SignalTap tap(signals, 4);
  tap.capture(3, 0);
  std::vector<double> rows;
  ASSERT_EQ(tap.drain(rows), 1u);
  const std::vector<double> expected = {3.0, 0.0, 100, 101, 102, 103, 107, 104, 105, 108, 109};
  EXPECT_EQ(rows, expected);
  for (std::size_t i = 0; i < signals.size(); ++i) {
    if (signals[i].size() > 0) {
      EXPECT_EQ(rows[tap.column(i)], *signals[i].data) << signals[i].block;
    }
  }
}
struct ParamsFixture : ::testing::Test {
  lode::Diagnostics diag;
  lode::Params load(const std::string& text) {
    node = YAML::Load(text);
    return lode::detail::make_params(node, "blocks.b", "test.yaml", &diag);
  }
  YAML::Node node;
};

// A field's own problem once: what a plugin checks of a missing required field afterwards
// (its defaulted value's size and sign) is a consequence, and the same message twice is one.
// Different problems of one field (two bad elements) are all said.
TEST_F(ParamsFixture, AMissingFieldIsOneProblemNotItsConsequences) {
  auto p = load("r: [-1, 2, -3]\n");
  const auto q = p.numbers("q");
  p.check(q.size() == 3, "q", "expected 3 numbers, got " + std::to_string(q.size()));
  for (int axis = 0; axis < 3; ++axis) p.check(false, "q", "must be > 0, got 0");
  const auto r = p.numbers("r");
  for (std::size_t i = 0; i < r.size(); ++i)
    p.check(r[i] > 0, "r", "element " + std::to_string(i) + " must be > 0, got " + std::to_string(r[i]));
  for (int twice = 0; twice < 2; ++twice) p.check(false, "r", "the same problem");
  EXPECT_FALSE(p.ok());
  const auto text = diag.format();
  EXPECT_NE(text.find("blocks.b.q: missing required parameter 'q'"), std::string::npos) << text;
  EXPECT_EQ(text.find("expected 3 numbers"), std::string::npos) << text;
  EXPECT_EQ(text.find("must be > 0, got 0"), std::string::npos) << text;
  EXPECT_NE(text.find("element 0 must be > 0"), std::string::npos) << text;
  EXPECT_NE(text.find("element 2 must be > 0"), std::string::npos) << text;
  EXPECT_EQ(text.find("the same problem"), text.rfind("the same problem")) << text;
  EXPECT_EQ(diag.size(), 4u) << text;
}

TEST_F(ParamsFixture, ReportsLocatedErrorsAndUnknownKeys) {
  auto p = load("gain: 2.5\nmode: fast\nlimit: abc\ngian_typo: 1\n");
  EXPECT_DOUBLE_EQ(p.number("gain"), 2.5);
  EXPECT_EQ(p.choice("mode", {"slow", "exact"}, "slow"), "slow");
  p.number("limit");
  p.number("required_one");
  lode::detail::report_unread_keys(p);
  const auto text = diag.format();
  EXPECT_NE(text.find("test.yaml:2:7: blocks.b.mode: 'fast' is not one of: slow, exact"), std::string::npos) << text;
  EXPECT_NE(text.find("test.yaml:3:8: blocks.b.limit: expected a finite number, got 'abc'"), std::string::npos) << text;
  EXPECT_NE(text.find("missing required parameter 'required_one'"), std::string::npos) << text;
  EXPECT_NE(text.find("test.yaml:4:1: blocks.b.gian_typo: unknown parameter 'gian_typo'"), std::string::npos) << text;
  EXPECT_FALSE(p.ok());
}

TEST_F(ParamsFixture, ListsAndNestedMaps) {
  auto p = load("q: [1, 2, 3]\naxes:\n  - {k: 1}\n  - {k: 2, extra: 3}\n");
  EXPECT_EQ(p.numbers("q", 3).size(), 3u);
  p.numbers("q", 2);
  auto items = p.items("axes");
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[1].number("k"), 2.0);
  items[0].number("k");
  items.clear();  // plugins often read nested maps through temporaries
  lode::detail::report_unread_keys(p);
  const auto text = diag.format();
  EXPECT_NE(text.find("expected 2 numbers, got 3"), std::string::npos) << text;
  EXPECT_NE(text.find("blocks.b.axes[1].extra: unknown parameter"), std::string::npos) << text;
}

TEST_F(ParamsFixture, OneNumberIsSpreadToEveryElementAndAWrongCountIsReportedOnItsKey) {
  auto p = load("kp: 2\nkd: [1, 2]\nki: [1, 2, 3]\n");
  EXPECT_EQ(p.one_or_each("kp", p.numbers("kp"), 3, "axis"), (std::vector<double>{2, 2, 2}));
  EXPECT_EQ(p.one_or_each("ki", p.numbers("ki"), 3, "axis"), (std::vector<double>{1, 2, 3}));
  EXPECT_TRUE(p.ok());
  // Two for three axes: reported, and padded with the last so the caller may still index it.
  EXPECT_EQ(p.one_or_each("kd", p.numbers("kd"), 3, "axis"), (std::vector<double>{1, 2, 2}));
  const auto text = diag.format();
  EXPECT_NE(text.find("test.yaml:2:5: blocks.b.kd: expected one number or 3 (one per axis), got 2"), std::string::npos)
      << text;
  EXPECT_FALSE(p.ok());
}

TEST_F(ParamsFixture, FilePathsAreRelativeToTheConfigFilesDirectory) {
  node = YAML::Load("map: maps/board.regmap\nup: ../b.regmap\nabs: /etc/b.regmap\nempty: ''\nnum: 3\n");
  auto p = lode::detail::make_params(node, "blocks.b", "/srv/cfg/pipe.yaml", &diag);
  EXPECT_EQ(p.file_path("map", ""), "/srv/cfg/maps/board.regmap");
  EXPECT_EQ(p.file_path("up", ""), "/srv/b.regmap");
  EXPECT_EQ(p.file_path("abs", ""), "/etc/b.regmap");
  EXPECT_EQ(p.file_path("empty", "x"), "");
  EXPECT_EQ(p.file_path("absent", "built-in"), "built-in");  // the fallback as given
  EXPECT_TRUE(p.ok()) << diag.format();
  // A pipeline built from text under a bare label: relative to the working directory.
  auto q = lode::detail::make_params(node, "blocks.b", "label.yaml", &diag);
  EXPECT_EQ(q.file_path("map", ""), "maps/board.regmap");
  node["num"] = YAML::Load("[1, 2]");
  EXPECT_EQ(p.file_path("num", ""), "");  // not a text: reported at the key
  EXPECT_NE(diag.format().find("/srv/cfg/pipe.yaml:"), std::string::npos) << diag.format();
  EXPECT_NE(diag.format().find("blocks.b.num: expected a text"), std::string::npos) << diag.format();
}

TEST(RealClock, SpinningSleepNeverReturnsEarlyAndBurnsOnlyTheSpin) {
  // realtime.spin_us: sleep until spin before the deadline, busy-wait the rest.
  for (const std::int64_t spin_ns : {std::int64_t{0}, std::int64_t{200'000}}) {
    lode::RealClock clock(spin_ns);
    std::int64_t worst_late = 0;
    timespec cpu0{}, cpu1{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu0);
    for (int i = 0; i < 20; ++i) {
      const std::int64_t deadline = clock.now_ns() + 1'000'000;  // 1 ms ahead
      clock.sleep_until(deadline);
      const std::int64_t late = clock.now_ns() - deadline;
      ASSERT_GE(late, 0) << "returned before the deadline (spin " << spin_ns << " ns)";
      worst_late = std::max(worst_late, late);
    }
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu1);
    const double cpu_ms = (cpu1.tv_sec - cpu0.tv_sec) * 1e3 + (cpu1.tv_nsec - cpu0.tv_nsec) * 1e-6;
    std::printf("spin %lld ns: worst lateness %lld ns, CPU %.2f ms for 20 ms of waiting\n",
                static_cast<long long>(spin_ns), static_cast<long long>(worst_late), cpu_ms);
    // Spinning 0.2 ms of each 1 ms wait burns at most ~the spin (plus the sleeps' overhead);
    // it never spins the whole millisecond.
    EXPECT_LT(cpu_ms, spin_ns > 0 ? 12.0 : 5.0);
  }
}

TEST(Json, DumpsOrderedAndEscaped) {
  lode::Json j = lode::Json::object();
  j["b"] = 1.5;
  j["a"] = "x\"y";
  j["v"] = std::vector<double>{1, 2};
  EXPECT_EQ(j.dump(-1), R"({"b": 1.5, "a": "x\"y", "v": [1, 2]})");
}

}  // namespace
