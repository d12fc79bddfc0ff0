// Counts heap allocations in the whole test process, dlopen'ed plugins included.
//
//   const auto before = lode::testing::allocation_count();
//   ... run step() ...
//   EXPECT_EQ(lode::testing::allocation_count() - before, 0u);
//
// Linking this into a test replaces malloc, calloc, realloc, the aligned allocators and
// (through them) operator new, so Eigen's aligned buffers are seen too. Under
// AddressSanitizer, which owns the allocator, nothing is counted:
// allocation_counting_available() says so and the guard test skips.
#pragma once

#include <cstddef>

namespace lode::testing {

/// Allocations made by any thread since the process started.
std::size_t allocation_count() noexcept;

/// False in sanitizer builds, where the count stays 0.
bool allocation_counting_available() noexcept;

}  // namespace lode::testing
