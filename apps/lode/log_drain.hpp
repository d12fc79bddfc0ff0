// Drains the RT log ring into spdlog (and warnings into the event log), off the RT thread.
// Under systemd (stderr is the journal) each record is a line on stderr whose "<N>" prefix
// carries its level, instead of spdlog's timestamped line on stdout.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "lode/event_log.hpp"

namespace lode {

class LogDrain {
 public:
  /// Starts the thread, which drains every `pause`.
  explicit LogDrain(EventLog& events, std::chrono::milliseconds pause = std::chrono::milliseconds(20));
  ~LogDrain();
  LogDrain(const LogDrain&) = delete;
  LogDrain& operator=(const LogDrain&) = delete;
  /// Format whatever is queued now (also called by the drain thread every `pause`).
  void drain_once();
  /// Wake and stop the thread (without waiting out its pause), drain the rest, and report
  /// drops as an event.
  void stop();

 private:
  EventLog& events_;
  const bool journal_;
  std::atomic<bool> running_{true};
  // The thread's pause between drains: stop() wakes it, so that stopping costs no more than
  // the last drain (`lode replay` stops it inside the wall time it reports, `lode run` at its
  // end: up to a whole pause each, when they slept it out).
  std::mutex pause_mutex_;
  std::condition_variable pause_;
  std::thread thread_;
  std::uint64_t reported_drops_ = 0;
};

}  // namespace lode
