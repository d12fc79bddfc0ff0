// The monotonic clock the RT path reads (CLOCK_MONOTONIC, ns): no allocation, no lock; on
// Linux a vDSO call, not a system call.
#pragma once

#include <time.h>

#include <cstdint>

namespace lode {

inline std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// CLOCK_REALTIME in ns: the clock of the kernel's socket receive timestamps (SO_TIMESTAMPNS),
/// so a send time taken here and a frame's receive time can be subtracted.
inline std::int64_t realtime_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace lode
