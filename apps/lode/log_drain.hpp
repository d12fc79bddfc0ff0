// Drains the RT log ring into spdlog (and warnings into the event log), off the RT thread.
// Under systemd (stderr is the journal) each record is a line on stderr whose "<N>" prefix
// carries its level, instead of spdlog's timestamped line on stdout.
#pragma once

#include <atomic>
#include <thread>

#include "lode/event_log.hpp"

namespace lode {

class LogDrain {
 public:
  explicit LogDrain(EventLog& events);
  ~LogDrain();
  LogDrain(const LogDrain&) = delete;
  LogDrain& operator=(const LogDrain&) = delete;
  /// Format whatever is queued now (also called by the drain thread every 20 ms).
  void drain_once();
  /// Stop the thread, drain the rest, and report drops as an event.
  void stop();

 private:
  EventLog& events_;
  const bool journal_;
  std::atomic<bool> running_{true};
  std::thread thread_;
  std::uint64_t reported_drops_ = 0;
};

}  // namespace lode
