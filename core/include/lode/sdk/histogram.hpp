// Latency / execution-time histogram with fixed storage: safe to record from the RT thread.
//
// Log-linear bins (HDR-histogram style): 32 sub-bins per power of two from 1 ns to ~68 s,
// so any percentile is known to within ~3 % with no allocation. One writer (the RT thread);
// readers on other threads see relaxed but untorn counters.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "lode/sdk/json.hpp"

namespace lode {

class Histogram {
 public:
  static constexpr int kSubBits = 5;
  static constexpr int kSub = 1 << kSubBits;
  static constexpr int kOctaves = 37;
  static constexpr int kBins = kSub * kOctaves;

  void record(std::int64_t value_ns) noexcept;
  void reset() noexcept;

  [[nodiscard]] std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::int64_t max() const noexcept { return max_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::int64_t min() const noexcept;
  [[nodiscard]] double mean() const noexcept;
  /// Upper edge of the bin holding quantile q in [0, 1] (conservative), clamped to max().
  [[nodiscard]] std::int64_t percentile(double q) const noexcept;
  /// {count, min, p50, p90, p99, p99.9, max, mean} in microseconds.
  [[nodiscard]] Json summary_us() const;
  /// Calls visit(upper_edge_ns, count) for every non-empty bin, lowest first; the edge is
  /// clamped to max() as percentile() clamps it. For exporting the whole distribution.
  template <typename Visit>
  void for_each_bin(Visit&& visit) const {
    const std::int64_t largest = max();
    for (int i = 0; i < kBins; ++i) {
      const std::uint64_t n = bins_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
      if (n == 0) continue;
      const std::int64_t edge = upper_edge(i);
      visit(edge < largest ? edge : largest, n);
    }
  }

  static int bin_of(std::int64_t value) noexcept;
  static std::int64_t upper_edge(int bin) noexcept;

 private:
  std::array<std::atomic<std::uint64_t>, kBins> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::int64_t> max_{0};
  std::atomic<std::int64_t> min_{INT64_MAX};
  std::atomic<std::int64_t> sum_{0};
};

}  // namespace lode
