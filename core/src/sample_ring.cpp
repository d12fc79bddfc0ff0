#include "lode/sample_ring.hpp"

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
    : width_(width), stride_(kHeaderWords + width), index_(capacity), storage_(index_.capacity() * stride_, 0.0) {}

bool SampleRing::push(const SampleHeader& header, const double* values) noexcept {
  return push(header, values, width_, nullptr, 0, nullptr, 0);
}

bool SampleRing::push(const SampleHeader& header, const double* a, std::size_t na, const double* b,
                      std::size_t nb, const double* c, std::size_t nc) noexcept {
  double* v = claim();
  if (v == nullptr) return false;
  if (na) std::memcpy(v, a, na * sizeof(double));
  if (nb) std::memcpy(v + na, b, nb * sizeof(double));
  if (nc) std::memcpy(v + na + nb, c, nc * sizeof(double));
  publish(header);
  return true;
}

double* SampleRing::claim() noexcept {
  if (!index_.claim(claimed_)) return nullptr;
  return storage_.data() + claimed_ * stride_ + kHeaderWords;
}

void SampleRing::publish(const SampleHeader& header) noexcept {
  write_header(storage_.data() + claimed_ * stride_, header);
  index_.publish();
}

const double* SampleRing::front(SampleHeader& header) const noexcept {
  std::size_t slot = 0;
  if (!index_.front(slot)) return nullptr;
  const double* rec = storage_.data() + slot * stride_;
  std::memcpy(&header.cycle, rec + 0, sizeof(double));
  std::memcpy(&header.stamp_ns, rec + 1, sizeof(double));
  std::memcpy(&header.captured_ns, rec + 2, sizeof(double));
  return rec + kHeaderWords;
}

void SampleRing::pop() noexcept { index_.release(); }

}  // namespace lode
