// The real-time contract, measured: no heap allocation in any step() of any shipped
// pipeline over 1e5 cycles. Every malloc-family call in the process is counted while the
// cycles run (operator new ends in malloc, Eigen's aligned allocation too), including
// calls made from the dlopen'ed plugins.
#include <gtest/gtest.h>
#include <malloc.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);
}

namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::size_t> g_allocations{0};
inline void count() {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t m) {
  count();
  return __libc_calloc(n, m);
}
void* realloc(void* p, size_t n) {
  count();
  return __libc_realloc(p, n);
}
void* memalign(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* aligned_alloc(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, size_t a, size_t n) {
  count();
  *out = __libc_memalign(a, n);
  return *out ? 0 : ENOMEM;
}
void free(void* p) { __libc_free(p); }
}

namespace {

class CountingScope {
 public:
  CountingScope() {
    g_allocations = 0;
    g_counting = true;
  }
  ~CountingScope() { g_counting = false; }
  static std::size_t count() { return g_allocations.load(); }
};

TEST(AllocationCounter, SeesAllocations) {
  // Guards the guard: the counter must see an ordinary allocation, or the test below
  // proves nothing.
  std::size_t seen = 0;
  {
    CountingScope scope;
    auto* v = new std::vector<double>(100);
    seen = CountingScope::count();
    delete v;
  }
  EXPECT_GE(seen, 2u);
}

std::vector<std::string> shipped_pipelines() {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(LODE_SOURCE_DIR "/config"))
    if (e.path().extension() == ".yaml") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

class NoAllocation : public ::testing::TestWithParam<std::string> {};

TEST_P(NoAllocation, HundredThousandCyclesAllocateNothing) {
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_file(GetParam(), registry, diag);
  ASSERT_TRUE(p) << diag.format();
  ASSERT_TRUE(p->activate());
  // The tap the runner uses is part of the RT path too.
  std::vector<lode::SignalRef> signals = p->signals();
  lode::SignalTap tap(signals, 1024);
  std::vector<double> drained;
  drained.reserve(1024 * tap.stride());
  lode::Tick tick;
  tick.dt_s = 1.0 / p->rate_hz();
  std::size_t allocations = 0;
  std::uint64_t faults = 0;
  {
    CountingScope scope;
    for (std::uint64_t k = 0; k < 100000; ++k) {
      tick.cycle = k;
      tick.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
      if (p->run_cycle(tick, true).status != lode::StepStatus::ok) ++faults;
      tap.capture(k, tick.time_ns);
      if ((k & 511) == 511) {
        g_counting = false;  // draining is the consumer's (non-RT) side
        drained.clear();
        tap.drain(drained);
        g_counting = true;
      }
    }
    allocations = CountingScope::count();
  }
  EXPECT_EQ(faults, 0u);
  EXPECT_EQ(allocations, 0u) << GetParam() << ": step() allocated";
  p->deactivate();
}

INSTANTIATE_TEST_SUITE_P(ShippedPipelines, NoAllocation, ::testing::ValuesIn(shipped_pipelines()),
                         [](const auto& case_info) {
                           return std::filesystem::path(case_info.param).stem().string();
                         });

}  // namespace
