// The event log: faults, start/stop, degraded RT settings, dropped log records.
// Non-RT only (the RT thread reports through rt_log(), whose warnings the drainer forwards).
//
// Bounded for a run of any length and any input: each text is cut to kMaxTextBytes, and the
// log keeps the first kKeptHead events (how the run started) and the latest kKeptTail. An
// event pushed out of memory is counted, never silently gone: the summary says how many, and
// a reader that fell behind is told how many it missed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "lode/sdk/json.hpp"

namespace lode {

struct Event {
  std::int64_t time_ns = 0;
  std::uint64_t cycle = 0;
  std::string kind;  ///< "start", "stop", "fault", "warning", "rt", ...
  std::string text;
};

class EventLog {
 public:
  static constexpr std::size_t kMaxTextBytes = 1024;
  static constexpr std::size_t kMaxKindBytes = 32;
  static constexpr std::size_t kKeptHead = 256;
  static constexpr std::size_t kKeptTail = 4096;
  /// post_limited(): events of one kind let through per second of wall time.
  static constexpr std::uint32_t kLimitedPerSecond = 10;

  void post(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text);
  /// post(), for what an outsider can cause at any rate (refused commands): at most
  /// kLimitedPerSecond events of `kind` per second; the rest are counted, and the next event
  /// of that kind let through says how many were suppressed before it.
  void post_limited(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text);
  /// Events post_limited() held back, all kinds.
  [[nodiscard]] std::uint64_t suppressed() const;
  /// The events kept in memory, oldest first (the head, then the tail).
  [[nodiscard]] std::vector<Event> snapshot() const;
  /// Events posted since `cursor` (the number of events posted when it was last advanced);
  /// advances the cursor. When some of them were already pushed out of memory, the first event
  /// returned is a "dropped" event saying how many.
  [[nodiscard]] std::vector<Event> since(std::size_t& cursor) const;
  [[nodiscard]] Json to_json() const;
  /// Every event ever posted, kept or not.
  [[nodiscard]] std::uint64_t posted() const;
  /// Events pushed out of memory (between the head and the tail).
  [[nodiscard]] std::uint64_t dropped() const;

 private:
  mutable std::mutex mutex_;
  std::vector<Event> head_;  ///< the first kKeptHead events
  std::deque<Event> tail_;   ///< the latest, at most kKeptTail
  std::uint64_t posted_ = 0;
  std::uint64_t dropped_ = 0;  ///< popped from the front of tail_
  struct Limiter {
    std::string kind;
    std::int64_t window_start_ns = 0;  ///< steady clock
    std::uint32_t in_window = 0;
    std::uint64_t held_back = 0;  ///< since the last one let through
  };
  std::vector<Limiter> limiters_;  ///< one per kind used with post_limited (a handful)
  std::uint64_t suppressed_ = 0;
};

/// `text` cut to at most `max_bytes` bytes (at a UTF-8 character boundary), with a note of how
/// much was cut: "...[cut 59880 bytes]".
std::string bounded_text(std::string text, std::size_t max_bytes);

}  // namespace lode
