#include "output_digest.hpp"

#include <xxhash.h>
#if defined(__x86_64__)
#define XXH_DISPATCH_DISABLE_REPLACE
#include <xxh_x86dispatch.h>
#endif

#include <cstdio>
#include <cstring>
#include <new>

namespace lode::cli {
namespace {

// The same XXH3 as XXH3_64bits_update, on x86-64 with the widest vector unit the CPU has
// (AVX2, AVX-512), chosen once at run time: Debian's libxxhash is built for baseline x86-64
// (SSE2), and on kawato_planar's 384 bytes the difference is measurable per cycle.
void xxh3_update(XXH3_state_t* state, const void* bytes, std::size_t size) noexcept {
#if defined(__x86_64__)
  (void)XXH3_64bits_update_dispatch(state, bytes, size);
#else
  (void)XXH3_64bits_update(state, bytes, size);
#endif
}

}  // namespace

const char* digest_algorithm_name(DigestAlgorithm algorithm) {
  return algorithm == DigestAlgorithm::xxh3_64 ? "xxh3-64" : "fnv1a-64";
}

std::optional<DigestAlgorithm> digest_algorithm_named(const std::string& name) {
  if (name.empty()) return kLegacyDigestAlgorithm;
  if (name == "xxh3-64") return DigestAlgorithm::xxh3_64;
  if (name == "fnv1a-64") return DigestAlgorithm::fnv1a_64;
  return std::nullopt;
}

std::uint64_t fnv1a_64(std::uint64_t hash, const void* data, std::size_t size) noexcept {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    hash ^= bytes[i];
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

// XXH3_state_t must be 64-byte aligned and its size is not part of the stable API:
// XXH3_createState allocates it (here, off the RT thread).
struct OutputDigest::XxhState {
  XXH3_state_t* state = XXH3_createState();
  ~XxhState() { XXH3_freeState(state); }
};

OutputDigest::OutputDigest(const std::vector<SignalRef>& signals, DigestAlgorithm algorithm)
    : algorithm_(algorithm), spans_(signals) {
  cycle_bytes_ = spans_.values() * sizeof(double);
  contiguous_ = reinterpret_cast<const unsigned char*>(spans_.contiguous());
  if (contiguous_ == nullptr) gather_.assign(spans_.values(), 0.0);
  if (algorithm_ == DigestAlgorithm::xxh3_64) {
    xxh_ = std::make_unique<XxhState>();
    if (xxh_->state == nullptr) throw std::bad_alloc();
  }
  reset();
  // The dispatcher picks its implementation (cpuid) on its first call: here, not on the RT
  // thread. No bytes: the state stays that of reset().
  if (xxh_) xxh3_update(xxh_->state, "", 0);
}

OutputDigest::~OutputDigest() = default;

void OutputDigest::reset() noexcept {
  fnv_ = kFnv1a64Offset;
  if (xxh_) XXH3_64bits_reset(xxh_->state);
}

void OutputDigest::after_cycle(const Tick&) noexcept {
  if (cycle_bytes_ == 0) return;
  const unsigned char* bytes = contiguous_;
  if (bytes == nullptr) {
    spans_.copy_to(gather_.data());
    bytes = reinterpret_cast<const unsigned char*>(gather_.data());
  }
  if (xxh_)
    xxh3_update(xxh_->state, bytes, cycle_bytes_);
  else
    fnv_ = fnv1a_64(fnv_, bytes, cycle_bytes_);
}

std::uint64_t OutputDigest::value() const noexcept { return xxh_ ? XXH3_64bits_digest(xxh_->state) : fnv_; }

std::string OutputDigest::text() const {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(value()));
  return buf;
}

}  // namespace lode::cli
