#include "lode/sdk/testing/allocation_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <new>  // NOLINT

namespace {
std::atomic<std::size_t> g_allocations{0};
// initial-exec: the variable lives in the executable's static TLS block, so reaching it
// never calls __tls_get_addr, which may itself allocate (and would recurse into malloc).
thread_local std::size_t t_allocations __attribute__((tls_model("initial-exec"))) = 0;
inline void count() noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
}
}  // namespace

namespace lode::testing {
std::size_t allocation_count() noexcept { return g_allocations.load(std::memory_order_relaxed); }
std::size_t thread_allocation_count() noexcept { return t_allocations; }
}  // namespace lode::testing

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)

// The sanitizer owns malloc and operator new and would not let us replace them; it calls an
// installed hook for every allocation it serves instead (any entry point, any thread).
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*on_malloc)(const volatile void*, std::size_t),
                                                         void (*on_free)(const volatile void*));

namespace {
void on_sanitizer_malloc(const volatile void*, std::size_t) { count(); }
void on_sanitizer_free(const volatile void*) {}
const bool g_hooked = __sanitizer_install_malloc_and_free_hooks(on_sanitizer_malloc, on_sanitizer_free) != 0;
}  // namespace

namespace lode::testing {
bool allocation_counting_available() noexcept { return g_hooked; }
}  // namespace lode::testing

#else

namespace lode::testing {
bool allocation_counting_available() noexcept { return true; }
}  // namespace lode::testing

// glibc's own entry points: the replacements below count and forward to them. glibc calls
// malloc through its interposable symbol, so its internal allocations (strdup, fopen,
// asprintf, ...) are counted too; the self-test checks each path.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
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
void* reallocarray(void* p, std::size_t n, std::size_t m) {
  std::size_t bytes = 0;
  if (__builtin_mul_overflow(n, m, &bytes)) {
    errno = ENOMEM;
    return nullptr;
  }
  count();
  return __libc_realloc(p, bytes);
}
void* memalign(std::size_t a, std::size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* valloc(std::size_t n) {
  count();
  return __libc_valloc(n);
}
void* pvalloc(std::size_t n) {
  count();
  return __libc_pvalloc(n);
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  count();
  *out = __libc_memalign(a, n);
  return *out ? 0 : ENOMEM;
}
void free(void* p) { __libc_free(p); }
}

#endif
