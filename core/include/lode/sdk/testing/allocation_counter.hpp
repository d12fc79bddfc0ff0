// Counts heap allocations in the whole test process, dlopen'ed plugins included.
//
//   LODE_REQUIRE_ALLOCATION_COUNTING();
//   const auto before = lode::testing::allocation_count();
//   ... run step() ...
//   EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
//
// Linking this into a test replaces malloc, calloc, realloc, reallocarray, valloc, pvalloc,
// memalign, aligned_alloc and posix_memalign, and so everything built on them: operator new
// in all its forms (plain, array, aligned, nothrow), Eigen's aligned buffers, strdup and the
// rest of libc. Under AddressSanitizer or ThreadSanitizer, which own the allocator, the count
// comes from the sanitizer's allocation hook instead: it sees the same calls, except that GCC
// 12's ThreadSanitizer serves posix_memalign, aligned_alloc, memalign, valloc and pvalloc
// without calling the hook (operator new, aligned or not, is seen).
//
// thread_allocation_count() counts the calling thread only, so a test can measure what one
// thread (the scheduler's cycle thread) allocates while other threads go on.
#pragma once

#include <cstddef>

namespace lode::testing {

/// Allocations made by any thread since the process started.
std::size_t allocation_count() noexcept;

/// Allocations made by the calling thread since it started.
std::size_t thread_allocation_count() noexcept;

/// True when the counts above see allocations. False only if the counter could not hook the
/// allocator (a sanitizer that refused the hook): a test must not pass on a count of zero then.
bool allocation_counting_available() noexcept;

}  // namespace lode::testing

/// First line of a test that asserts a count of zero: fails the test when allocations cannot
/// be counted in this build, so "no allocation" never passes because nothing was counted.
#define LODE_REQUIRE_ALLOCATION_COUNTING()                                                      \
  do {                                                                                         \
    if (!::lode::testing::allocation_counting_available()) {                                   \
      GTEST_FAIL() << "heap allocations cannot be counted in this build, so an allocation-free " \
                      "step() cannot be verified";                                             \
    }                                                                                          \
  } while (false)
