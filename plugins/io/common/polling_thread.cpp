#include "polling_thread.hpp"

#include <utility>

namespace lode::plugins::boards {

void PollingThread::start(std::function<bool()> poll, std::function<void()> idle) {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this, poll = std::move(poll), idle = std::move(idle)] {
    while (running_.load(std::memory_order_relaxed)) {
      if (!poll()) idle();
    }
  });
}

void PollingThread::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

}  // namespace lode::plugins::boards
