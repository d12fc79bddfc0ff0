// The RT log's drain thread: stopping it does not wait out its pause between drains (lode
// replay stops it inside the wall time it reports), and what was logged before the stop is
// drained by it.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "log_drain.hpp"
#include "lode/event_log.hpp"
#include "lode/sdk/rt_log.hpp"

namespace {

using namespace std::chrono_literals;

TEST(LogDrain, StopWakesTheThreadInsteadOfWaitingOutItsPause) {
  lode::EventLog events;
  lode::LogDrain drain(events, 30s);
  std::this_thread::sleep_for(50ms);  // the thread has drained once and is in its pause
  const auto start = std::chrono::steady_clock::now();
  drain.stop();
  // Slept out, the pause would take 30 s; a woken thread returns at once. The bound is far
  // from both so that a loaded machine cannot make it flaky.
  EXPECT_LT(std::chrono::steady_clock::now() - start, 10s);
}

TEST(LogDrain, StopDrainsWhatWasLoggedBeforeIt) {
  lode::EventLog events;
  lode::LogDrain drain(events, 30s);
  std::this_thread::sleep_for(50ms);
  lode::rt_log(lode::LogLevel::warn, "test", "logged during the pause {}", 7.0);
  drain.stop();
  bool found = false;
  for (const auto& e : events.snapshot()) found = found || e.text.find("logged during the pause 7") != std::string::npos;
  EXPECT_TRUE(found);
}

}  // namespace
