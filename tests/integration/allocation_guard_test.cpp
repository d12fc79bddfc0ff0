// The allocation guard guarded: every allocator path the counter claims to see is seen, on
// the thread that allocates, when the allocation happens inside a dlopen'ed plugin's step()
// run by the scheduler, with the same measurement the no-allocation sweep uses. A guard that
// missed a path would let a plugin that allocates that way pass the sweep.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "cycle_allocations.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"

namespace {

using lode::testing::allocation_count;
using lode::testing::thread_allocation_count;

/// Keeps the compiler from removing an allocation whose result is unused.
void escape(const void* p) { asm volatile("" : : "g"(p) : "memory"); }

/// Puts the test plugins (not shipped, not in the build's plugin folder) on the search path.
void find_test_plugins() {
  static const bool once = [] {
    const char* path = std::getenv("LODE_PLUGIN_PATH");
    const std::string joined = std::string(path ? path : "") + ":" + LODE_BAD_PLUGIN_DIR;
    return ::setenv("LODE_PLUGIN_PATH", joined.c_str(), 1) == 0;
  }();
  ASSERT_TRUE(once);
}

std::string leaking_pipeline(const std::string& path, int from_cycle) {
  return "pipeline: allocation_guard\nrate_hz: 1000\nblocks:\n"
         "  leak: { plugin: test.allocates_in_step, path: " + path + ", from_cycle: " + std::to_string(from_cycle) +
         " }\n";
}

const std::vector<std::string> kPaths = {"new",          "new_array",     "aligned_new",  "nothrow_new", "malloc",
                                         "calloc",       "realloc",       "reallocarray", "posix_memalign",
                                         "aligned_alloc", "memalign",     "valloc",       "pvalloc",     "strdup",
                                         "std_string",   "std_vector",    "eigen_dynamic", "shared_ptr"};

TEST(AllocationGuard, ThreadCountSeesOnlyItsOwnThread) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  const auto process_before = allocation_count();
  const auto thread_before = thread_allocation_count();
  std::thread other([] {
    void* p = std::malloc(64);
    escape(p);
    std::free(p);
  });
  other.join();
  const auto process_seen = allocation_count() - process_before;
  const auto thread_seen = thread_allocation_count() - thread_before;
  EXPECT_GE(process_seen, 1u) << "an allocation on another thread is not counted for the process";
  // std::thread itself allocates its state on this thread (1 allocation); the malloc above
  // must not appear here.
  EXPECT_LE(thread_seen, process_seen - 1) << "another thread's allocation was counted for this one";
}

class EveryAllocatorPath : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryAllocatorPath, IsCaughtInAPluginStepRunByTheScheduler) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
#if defined(__SANITIZE_THREAD__)
  // GCC 12's ThreadSanitizer owns the allocator and serves these five without calling its
  // allocation hook, the only place a TSan build can count from. The plain and the ASan
  // builds check them; a TSan build checks the race-freedom of the same code.
  for (const char* unhooked : {"posix_memalign", "aligned_alloc", "memalign", "valloc", "pvalloc"})
    if (GetParam() == unhooked) GTEST_SKIP() << GetParam() << " bypasses ThreadSanitizer's allocation hook";
#endif
  find_test_plugins();
  // 1000 cycles; the plugin allocates from cycle 500: at least 500 allocations, one per step.
  const auto run = lode::testing::measure_cycle_allocations(leaking_pipeline(GetParam(), 500), "guard.yaml",
                                                            {.cycles = 1000});
  ASSERT_TRUE(run.configured) << run.error;
  ASSERT_FALSE(run.faulted) << run.fault;
  EXPECT_EQ(run.cycles, 1000u);
  EXPECT_GE(run.allocations, 500u) << GetParam() << ": allocations in step() went unseen";
  std::printf("%-15s %zu allocations counted in 500 allocating steps\n", GetParam().c_str(), run.allocations);
}

INSTANTIATE_TEST_SUITE_P(AllocationGuard, EveryAllocatorPath, ::testing::ValuesIn(kPaths),
                         [](const auto& case_info) { return case_info.param; });

TEST(AllocationGuard, AQuietPluginCountsZero) {
  // The same pipeline with the allocation beyond the last cycle: the machinery around the
  // plugin (scheduler, hooks, recorder tap) contributes nothing, so the counts above are the
  // plugin's, and zero is reachable.
  LODE_REQUIRE_ALLOCATION_COUNTING();
  find_test_plugins();
  const auto run = lode::testing::measure_cycle_allocations(leaking_pipeline("malloc", 1000000), "guard.yaml",
                                                            {.cycles = 1000});
  ASSERT_TRUE(run.configured) << run.error;
  EXPECT_EQ(run.allocations, 0u);
}

TEST(AllocationGuard, CaughtOnTheRealTimeThreadToo) {
  // The real clock runs the cycle on the scheduler's own RT thread, not the caller's.
  LODE_REQUIRE_ALLOCATION_COUNTING();
  find_test_plugins();
  // Every executed step allocates (from cycle 0): at least one allocation per cycle run. (The
  // real clock may skip periods on a loaded machine, so count the cycles that ran.)
  const auto run = lode::testing::measure_cycle_allocations(leaking_pipeline("new", 0), "guard.yaml",
                                                            {.cycles = 200, .real_clock = true});
  ASSERT_TRUE(run.configured) << run.error;
  EXPECT_GE(run.cycles, 100u);
  EXPECT_GE(run.allocations, run.cycles);
  const auto quiet = lode::testing::measure_cycle_allocations(leaking_pipeline("new", 1000000), "guard.yaml",
                                                              {.cycles = 200, .real_clock = true});
  ASSERT_TRUE(quiet.configured) << quiet.error;
  EXPECT_EQ(quiet.allocations, 0u);
}

}  // namespace
