// The thread a board emulator plays the board on (the io plugins' tests, lode-vme-emu and
// lode-can-emu): poll() until stop(), and between polls that found nothing to do, whatever
// wait suits that board (a short sleep, or a wait for the next frame or deadline).
//
// Not for the RT thread: start() allocates and creates a thread.
#pragma once

#include <atomic>
#include <functional>
#include <thread>

namespace lode::plugins::boards {

class PollingThread {
 public:
  PollingThread() = default;
  ~PollingThread() { stop(); }
  PollingThread(const PollingThread&) = delete;
  PollingThread& operator=(const PollingThread&) = delete;

  /// Runs `poll` on a thread of its own until stop(); `idle` after each poll that returned
  /// false (did nothing). Does nothing when already running.
  void start(std::function<bool()> poll, std::function<void()> idle);
  /// Ends the loop after the current poll and joins the thread. Does nothing when not running.
  void stop();

 private:
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace lode::plugins::boards
