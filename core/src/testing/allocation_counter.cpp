#include "lode/testing/allocation_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>  // NOLINT

namespace {
std::atomic<std::size_t> g_allocations{0};
inline void count() noexcept { g_allocations.fetch_add(1, std::memory_order_relaxed); }
}  // namespace

namespace lode::testing {
std::size_t allocation_count() noexcept { return g_allocations.load(std::memory_order_relaxed); }
}  // namespace lode::testing

#if defined(__SANITIZE_ADDRESS__)

// AddressSanitizer owns malloc and operator new, and g++ 12's runtime refuses allocation
// hooks (__sanitizer_install_malloc_and_free_hooks returns 0): nothing is counted.
namespace lode::testing {
bool allocation_counting_available() noexcept { return false; }
}  // namespace lode::testing

#else

namespace lode::testing {
bool allocation_counting_available() noexcept { return true; }
}  // namespace lode::testing

// glibc's own entry points: the replacements below count and forward to them.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);

void* malloc(std::size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t m) {
  count();
  return __libc_calloc(n, m);
}
void* realloc(void* p, std::size_t n) {
  count();
  return __libc_realloc(p, n);
}
void* memalign(std::size_t a, std::size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  count();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  count();
  *out = __libc_memalign(a, n);
  return *out ? 0 : ENOMEM;
}
void free(void* p) { __libc_free(p); }
}

#endif
