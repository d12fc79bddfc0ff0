// A wait-free single-producer single-consumer ring of fixed-width sample records (the
// SpscRingIndex of lode/spsc_ring.hpp over one allocation of records).
//
// The producer is the RT thread: push() never blocks, never allocates and never makes a
// system call; when the ring is full the record is dropped and counted (the consumer is
// too slow), so a stalled consumer costs the RT loop one failed comparison. The consumer is
// one non-RT thread. Storage is allocated once, in the constructor.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lode/spsc_ring.hpp"

namespace lode {

struct SampleHeader {
  std::uint64_t cycle = 0;
  std::int64_t stamp_ns = 0;     ///< scheduled time of the cycle since the start of the run
  std::int64_t captured_ns = 0;  ///< CLOCK_MONOTONIC when the RT thread copied the values
};

class SampleRing {
 public:
  /// `capacity` records of `width` values each (capacity is rounded up to a power of two).
  SampleRing(std::size_t width, std::size_t capacity);

  /// Producer (RT). False (and counted) when the ring is full.
  bool push(const SampleHeader& header, const double* values) noexcept;
  /// Producer (RT), gathering up to three pieces into one record (total = width()).
  bool push(const SampleHeader& header, const double* a, std::size_t na, const double* b,
            std::size_t nb, const double* c, std::size_t nc) noexcept;
  /// Producer (RT), for records gathered from many pieces: the values of the next record
  /// (width() of them) to fill, or nullptr when the ring is full (counted); then publish().
  double* claim() noexcept;
  void publish(const SampleHeader& header) noexcept;

  /// Consumer: pointer to the oldest record's values (nullptr if empty); valid until pop().
  const double* front(SampleHeader& header) const noexcept;
  void pop() noexcept;

  [[nodiscard]] std::size_t width() const noexcept { return width_; }
  [[nodiscard]] std::size_t capacity() const noexcept { return index_.capacity(); }
  [[nodiscard]] std::size_t size() const noexcept { return index_.size(); }
  [[nodiscard]] std::uint64_t pushed() const noexcept { return index_.pushed(); }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return index_.dropped(); }

 private:
  std::size_t width_;
  std::size_t stride_;  ///< doubles per record: 3 header words + width
  SpscRingIndex index_;
  std::vector<double> storage_;
  std::size_t claimed_ = 0;  ///< the producer's slot between claim() and publish()
};

}  // namespace lode
