// The one single-producer single-consumer ring of lodestone: the RT thread produces, one
// non-RT thread consumes. push never blocks, never allocates and makes no system call; a
// full ring drops the record and counts it, so a stalled consumer costs the RT loop one
// comparison. SpscRingIndex is the index discipline, for records of any layout in storage
// the owner allocates once (SampleRing: variable-width samples); SpscQueue holds fixed
// values (the health monitor's trips).
#pragma once

#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace lode {

class SpscRingIndex {
 public:
  /// `capacity` slots, rounded up to a power of two (at least 2).
  explicit SpscRingIndex(std::size_t capacity)
      : mask_(std::bit_ceil(capacity < 2 ? std::size_t{2} : capacity) - 1) {}

  /// Producer: the slot to fill next; false (and the drop counted) when the ring is full.
  /// The consumer's index (a cache line it writes) is read only when the cached copy says
  /// full: one shared-line read per lap instead of one per record.
  bool claim(std::size_t& slot) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - cached_tail_ > mask_) {
      cached_tail_ = tail_.load(std::memory_order_acquire);
      if (head - cached_tail_ > mask_) {
        dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
        return false;
      }
    }
    slot = static_cast<std::size_t>(head & mask_);
    return true;
  }
  /// Producer: the claimed slot is filled; the consumer may read it.
  void publish() noexcept { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  /// Consumer: the oldest filled slot; false when the ring is empty.
  bool front(std::size_t& slot) const noexcept {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    slot = static_cast<std::size_t>(tail & mask_);
    return true;
  }
  /// Consumer: the oldest slot is read; the producer may reuse it.
  void release() noexcept {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    if (tail != head_.load(std::memory_order_acquire)) tail_.store(tail + 1, std::memory_order_release);
  }

  [[nodiscard]] std::size_t capacity() const noexcept { return mask_ + 1; }
  [[nodiscard]] std::size_t size() const noexcept {
    return static_cast<std::size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }
  [[nodiscard]] std::uint64_t pushed() const noexcept { return head_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::size_t mask_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  ///< written by the producer only
  std::uint64_t cached_tail_ = 0;                    ///< the producer's last view of tail_
  alignas(64) std::atomic<std::uint64_t> tail_{0};  ///< written by the consumer only
  alignas(64) std::atomic<std::uint64_t> dropped_{0};
};

/// Values of a trivially copyable type through an SpscRingIndex.
template <typename T>
class SpscQueue {
 public:
  explicit SpscQueue(std::size_t capacity) : index_(capacity), slots_(index_.capacity()) {}
  /// Producer (RT): false (and counted) when full.
  bool push(const T& value) noexcept {
    std::size_t slot = 0;
    if (!index_.claim(slot)) return false;
    slots_[slot] = value;
    index_.publish();
    return true;
  }
  /// Consumer: the oldest value; false when empty.
  bool pop(T& out) noexcept {
    std::size_t slot = 0;
    if (!index_.front(slot)) return false;
    out = slots_[slot];
    index_.release();
    return true;
  }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return index_.dropped(); }
  [[nodiscard]] std::size_t size() const noexcept { return index_.size(); }

 private:
  SpscRingIndex index_;
  std::vector<T> slots_;
};

}  // namespace lode
