#include "lode/sdk/histogram.hpp"

#include <bit>

namespace lode {

int Histogram::bin_of(std::int64_t value) noexcept {
  if (value < kSub) return value < 0 ? 0 : static_cast<int>(value);
  const auto v = static_cast<std::uint64_t>(value);
  const int msb = 63 - std::countl_zero(v);          // >= kSubBits
  const int octave = msb - kSubBits + 1;             // 1.. for v >= kSub
  const int sub = static_cast<int>((v >> (msb - kSubBits)) & (kSub - 1));
  const int bin = octave * kSub + sub;
  return bin < kBins ? bin : kBins - 1;
}

std::int64_t Histogram::upper_edge(int bin) noexcept {
  const int octave = bin / kSub;
  const int sub = bin % kSub;
  if (octave == 0) return sub + 1;
  const int shift = octave - 1;
  return (static_cast<std::int64_t>(kSub + sub + 1) << shift);
}

void Histogram::record(std::int64_t value_ns) noexcept {
  auto& b = bins_[static_cast<std::size_t>(bin_of(value_ns))];
  b.store(b.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  count_.store(count_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  sum_.store(sum_.load(std::memory_order_relaxed) + value_ns, std::memory_order_relaxed);
  if (value_ns > max_.load(std::memory_order_relaxed)) max_.store(value_ns, std::memory_order_relaxed);
  if (value_ns < min_.load(std::memory_order_relaxed)) min_.store(value_ns, std::memory_order_relaxed);
}

void Histogram::reset() noexcept {
  for (auto& b : bins_) b.store(0, std::memory_order_relaxed);
  count_.store(0, std::memory_order_relaxed);
  max_.store(0, std::memory_order_relaxed);
  min_.store(INT64_MAX, std::memory_order_relaxed);
  sum_.store(0, std::memory_order_relaxed);
}

std::int64_t Histogram::min() const noexcept {
  const auto m = min_.load(std::memory_order_relaxed);
  return m == INT64_MAX ? 0 : m;
}

double Histogram::mean() const noexcept {
  const auto n = count();
  return n ? static_cast<double>(sum_.load(std::memory_order_relaxed)) / static_cast<double>(n) : 0.0;
}

std::int64_t Histogram::percentile(double q) const noexcept {
  const auto n = count();
  if (n == 0) return 0;
  const auto target = static_cast<std::uint64_t>(q * static_cast<double>(n - 1)) + 1;
  std::uint64_t seen = 0;
  for (int i = 0; i < kBins; ++i) {
    seen += bins_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
    if (seen >= target) {
      const auto edge = upper_edge(i);
      return edge < max() ? edge : max();
    }
  }
  return max();
}

Json Histogram::summary_us() const {
  Json j = Json::object();
  auto us = [](std::int64_t ns) { return static_cast<double>(ns) / 1000.0; };
  j["count"] = count();
  j["min_us"] = us(min());
  j["p50_us"] = us(percentile(0.50));
  j["p90_us"] = us(percentile(0.90));
  j["p99_us"] = us(percentile(0.99));
  j["p999_us"] = us(percentile(0.999));
  j["max_us"] = us(max());
  j["mean_us"] = mean() / 1000.0;
  return j;
}

}  // namespace lode
