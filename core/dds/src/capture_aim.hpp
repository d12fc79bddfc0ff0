// When the publisher thread should be awake for the RT thread's next samples. Private to
// the bridge.
//
// The RT thread copies a cycle's values at a moment that varies from cycle to cycle (its
// own wake-up latency plus the blocks before the copy). A publisher asleep on the doorbell
// costs the RT thread a FUTEX_WAKE system call; one that sleeps until after the capture
// (as it did) adds its own timer wake-up and the capture's spread to every sample's
// latency: 40 us and more at 1 kHz on an idle VM, where every wake-up is from idle. So it
// aims to be awake just before the earliest usual capture (the 10th percentile of the
// capture's delay, less how late its own timer usually fires) and then polls the doorbell
// for at most `spin_budget()`: 1/20 of the publishing period, at most 50 us (5 % of a CPU
// at 1 kHz). If the capture has not come by then, it sleeps until the latest usual capture
// (the 98th percentile), then looks again every `spin_budget()` until the next cycle is due,
// and only then waits on the doorbell: only a capture later than a whole period (a loop that
// skipped a period or stopped) finds it asleep there, and the ring makes the system call.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>

namespace lode::dds::bridge_detail {

/// A streaming estimate of a quantile of a stream of durations: up `up_ns` when a value is
/// above it, down `down_ns` when below. It settles where the steps balance, at the quantile
/// q = up_ns / (up_ns + down_ns), and follows a drift within a few hundred values.
class QuantileTracker {
 public:
  QuantileTracker(std::int64_t up_ns, std::int64_t down_ns) : up_ns_(up_ns), down_ns_(down_ns) {}
  void add(std::int64_t value_ns) {
    if (!known_) {
      value_ns_ = value_ns;
      known_ = true;
    } else if (value_ns > value_ns_) {
      value_ns_ += up_ns_;
    } else if (value_ns < value_ns_) {
      value_ns_ -= down_ns_;
    }
  }
  [[nodiscard]] bool known() const { return known_; }
  [[nodiscard]] std::int64_t value_ns() const { return value_ns_; }

 private:
  std::int64_t up_ns_, down_ns_;
  std::int64_t value_ns_ = 0;
  bool known_ = false;
};

class CaptureAim {
 public:
  /// Nanoseconds between two cycles that publish something.
  void set_step_ns(std::int64_t step_ns) { step_ns_ = step_ns; }
  /// Every record drained: its scheduled time and when the RT thread copied it, both
  /// CLOCK_MONOTONIC based (captured - stamp is the run's start plus the capture's delay).
  void learn_capture(std::int64_t stamp_ns, std::int64_t captured_ns) {
    early_.add(captured_ns - stamp_ns);
    late_.add(captured_ns - stamp_ns);
    last_stamp_ns_ = std::max(last_stamp_ns_, stamp_ns);
  }
  /// After each aimed sleep: how much later than asked the thread woke.
  void learn_oversleep(std::chrono::steady_clock::duration late) {
    oversleep_.add(std::max<std::int64_t>(0, std::chrono::duration_cast<std::chrono::nanoseconds>(late).count()));
  }
  /// How long to poll the doorbell once awake.
  [[nodiscard]] std::chrono::nanoseconds spin_budget() const {
    return std::chrono::nanoseconds(std::clamp<std::int64_t>(step_ns_ / 20, 0, 50'000));
  }
  struct Aim {
    std::chrono::steady_clock::time_point wake;  ///< be awake and polling from then
    std::chrono::steady_clock::time_point late;  ///< the latest usual capture (98th percentile)
    /// The earliest usual capture of the cycle after: past it, the loop skipped a period or stopped.
    std::chrono::steady_clock::time_point next_cycle;
  };
  /// When to be awake for the next records; nullopt until a capture was seen.
  [[nodiscard]] std::optional<Aim> next() const {
    if (!early_.known()) return std::nullopt;
    const std::int64_t scheduled = last_stamp_ns_ + step_ns_;
    const std::int64_t wake = scheduled + early_.value_ns() - oversleep_.value_ns();
    const std::int64_t late = scheduled + std::max(early_.value_ns(), late_.value_ns());
    // steady_clock is CLOCK_MONOTONIC, the clock of captured_ns.
    using tp = std::chrono::steady_clock::time_point;
    return Aim{tp(std::chrono::nanoseconds(wake)), tp(std::chrono::nanoseconds(late)),
               tp(std::chrono::nanoseconds(scheduled + step_ns_ + early_.value_ns()))};
  }

 private:
  std::int64_t step_ns_ = 0;
  std::int64_t last_stamp_ns_ = 0;
  QuantileTracker early_{100, 900};      ///< 10th percentile of the capture's offset
  QuantileTracker late_{1000, 20};       ///< 98th percentile
  QuantileTracker oversleep_{500, 500};  ///< median lateness of the publisher's timer
};

}  // namespace lode::dds::bridge_detail
