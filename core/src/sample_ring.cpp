#include "lode/sample_ring.hpp"

#include <bit>
#include <cstring>

namespace lode {

namespace {
constexpr std::size_t kHeaderWords = 3;  // cycle, stamp_ns, captured_ns stored bit for bit

void write_header(double* rec, const SampleHeader& h) noexcept {
  std::memcpy(rec + 0, &h.cycle, sizeof(double));
  std::memcpy(rec + 1, &h.stamp_ns, sizeof(double));
  std::memcpy(rec + 2, &h.captured_ns, sizeof(double));
}
}  // namespace

SampleRing::SampleRing(std::size_t width, std::size_t capacity)
    : width_(width),
      stride_(kHeaderWords + width),
      mask_(std::bit_ceil(capacity < 2 ? std::size_t{2} : capacity) - 1),
      storage_((mask_ + 1) * stride_, 0.0) {}

bool SampleRing::push(const SampleHeader& header, const double* values) noexcept {
  return push(header, values, width_, nullptr, 0, nullptr, 0);
}

bool SampleRing::push(const SampleHeader& header, const double* a, std::size_t na, const double* b,
                      std::size_t nb, const double* c, std::size_t nc) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  // Only look at the consumer's index (a cache line it writes) when our cached copy says
  // the ring is full: one shared-line read per lap instead of one per push.
  if (head - cached_tail_ > mask_) {
    cached_tail_ = tail_.load(std::memory_order_acquire);
    if (head - cached_tail_ > mask_) {
      dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      return false;
    }
  }
  double* rec = storage_.data() + (head & mask_) * stride_;
  write_header(rec, header);
  double* v = rec + kHeaderWords;
  if (na) std::memcpy(v, a, na * sizeof(double));
  if (nb) std::memcpy(v + na, b, nb * sizeof(double));
  if (nc) std::memcpy(v + na + nb, c, nc * sizeof(double));
  head_.store(head + 1, std::memory_order_release);
  return true;
}

const double* SampleRing::front(SampleHeader& header) const noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail == head_.load(std::memory_order_acquire)) return nullptr;
  const double* rec = storage_.data() + (tail & mask_) * stride_;
  std::memcpy(&header.cycle, rec + 0, sizeof(double));
  std::memcpy(&header.stamp_ns, rec + 1, sizeof(double));
  std::memcpy(&header.captured_ns, rec + 2, sizeof(double));
  return rec + kHeaderWords;
}

void SampleRing::pop() noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail != head_.load(std::memory_order_acquire)) tail_.store(tail + 1, std::memory_order_release);
}

std::size_t SampleRing::size() const noexcept {
  return static_cast<std::size_t>(head_.load(std::memory_order_acquire) -
                                  tail_.load(std::memory_order_acquire));
}

}  // namespace lode
