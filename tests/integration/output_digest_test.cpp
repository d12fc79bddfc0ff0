// The output digest against independent references: XXH3-64 streamed one cycle at a time equals
// libxxhash's one-shot XXH3_64bits over all cycles' outputs concatenated; FNV-1a equals its
// published test vectors; outputs spread over separate buffers (gathered each cycle) digest as
// the same values in one block do; a cycle allocates nothing.
#include "output_digest.hpp"

#include <gtest/gtest.h>
#include <xxhash.h>

#include <cstring>
#include <vector>

#include "lode/sdk/testing/allocation_counter.hpp"

namespace lode::cli {
namespace {

constexpr std::size_t kCycles = 100;

// Two outputs of 3 and 45 values (384 bytes a cycle, kawato_planar's size) whose values change
// every cycle the way a pipeline's do, written into `a` and `b` before each cycle.
struct Outputs {
  Elements ea = Elements(3), eb = Elements(45);
  void fill(std::size_t cycle, double* a, double* b) const {
    for (std::size_t i = 0; i < 3; ++i) a[i] = 0.25 * static_cast<double>(cycle) - static_cast<double>(i);
    for (std::size_t i = 0; i < 45; ++i) b[i] = 1e-6 * static_cast<double>(cycle * 45 + i) + 0.1;
  }
};

// Runs `cycles` cycles through a digest over `a` and `b`; `all` receives every cycle's bytes.
std::string run(const Outputs& o, double* a, double* b, DigestAlgorithm algorithm, std::vector<unsigned char>& all) {
  OutputDigest digest({{"x", "a", a, &o.ea}, {"x", "b", b, &o.eb}}, algorithm);
  Tick tick;
  for (std::size_t k = 0; k < kCycles; ++k) {
    o.fill(k, a, b);
    const auto* pa = reinterpret_cast<const unsigned char*>(a);
    const auto* pb = reinterpret_cast<const unsigned char*>(b);
    all.insert(all.end(), pa, pa + 3 * sizeof(double));
    all.insert(all.end(), pb, pb + 45 * sizeof(double));
    tick.cycle = k;
    digest.after_cycle(tick);
  }
  EXPECT_EQ(digest.cycle_bytes(), 48 * sizeof(double));
  return digest.text();
}

std::string hex(std::uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

TEST(OutputDigest, Xxh3StreamedPerCycleEqualsOneShotOverAllCycles) {
  Outputs o;
  std::vector<double> arena(48);
  std::vector<unsigned char> all;
  const std::string streamed = run(o, arena.data(), arena.data() + 3, DigestAlgorithm::xxh3_64, all);
  EXPECT_EQ(streamed, hex(XXH3_64bits(all.data(), all.size())));
}

TEST(OutputDigest, SeparateBuffersDigestAsOneBlock) {
  Outputs o;
  std::vector<double> arena(48), a(3), b(45);
  for (const auto algorithm : {DigestAlgorithm::xxh3_64, DigestAlgorithm::fnv1a_64}) {
    std::vector<unsigned char> all_contiguous, all_separate;
    const auto contiguous = run(o, arena.data(), arena.data() + 3, algorithm, all_contiguous);
    // b before a in memory, and apart: not one block in signal order.
    std::vector<double> storage(60);
    const auto separate = run(o, storage.data() + 50, storage.data(), algorithm, all_separate);
    EXPECT_EQ(all_contiguous, all_separate);
    EXPECT_EQ(contiguous, separate) << digest_algorithm_name(algorithm);
  }
}

TEST(OutputDigest, Fnv1aMatchesPublishedVectorsAndTheByteStream) {
  EXPECT_EQ(fnv1a_64(kFnv1a64Offset, "", 0), 0xcbf29ce484222325ULL);
  EXPECT_EQ(fnv1a_64(kFnv1a64Offset, "a", 1), 0xaf63dc4c8601ec8cULL);
  EXPECT_EQ(fnv1a_64(kFnv1a64Offset, "foobar", 6), 0x85944171f73967e8ULL);
  Outputs o;
  std::vector<double> arena(48);
  std::vector<unsigned char> all;
  const std::string streamed = run(o, arena.data(), arena.data() + 3, DigestAlgorithm::fnv1a_64, all);
  EXPECT_EQ(streamed, hex(fnv1a_64(kFnv1a64Offset, all.data(), all.size())));
}

TEST(OutputDigest, ResetStartsOver) {
  Outputs o;
  std::vector<double> arena(48);
  OutputDigest digest({{"x", "a", arena.data(), &o.ea}, {"x", "b", arena.data() + 3, &o.eb}}, DigestAlgorithm::xxh3_64);
  const auto empty = digest.value();
  EXPECT_EQ(empty, XXH3_64bits(nullptr, 0));
  digest.after_cycle(Tick{});
  EXPECT_NE(digest.value(), empty);
  digest.reset();
  EXPECT_EQ(digest.value(), empty);
}

TEST(OutputDigest, AlgorithmNames) {
  EXPECT_EQ(digest_algorithm_named(""), DigestAlgorithm::fnv1a_64);  // recordings made before the tag
  EXPECT_EQ(digest_algorithm_named("fnv1a-64"), DigestAlgorithm::fnv1a_64);
  EXPECT_EQ(digest_algorithm_named("xxh3-64"), DigestAlgorithm::xxh3_64);
  EXPECT_FALSE(digest_algorithm_named("md5").has_value());
  for (const auto a : {DigestAlgorithm::xxh3_64, DigestAlgorithm::fnv1a_64})
    EXPECT_EQ(digest_algorithm_named(digest_algorithm_name(a)), a);
}

TEST(OutputDigest, ACycleAllocatesNothing) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Outputs o;
  std::vector<double> storage(60);
  for (const auto algorithm : {DigestAlgorithm::xxh3_64, DigestAlgorithm::fnv1a_64}) {
    // Separate buffers: the gathering path, the one no shipped pipeline takes.
    OutputDigest digest({{"x", "a", storage.data() + 50, &o.ea}, {"x", "b", storage.data(), &o.eb}}, algorithm);
    const auto before = testing::thread_allocation_count();
    for (std::uint64_t k = 0; k < 1000; ++k) digest.after_cycle(Tick{k, 0, 0.0});
    EXPECT_EQ(testing::thread_allocation_count() - before, 0u) << digest_algorithm_name(algorithm);
  }
}

}  // namespace
}  // namespace lode::cli
