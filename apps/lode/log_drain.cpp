#include "log_drain.hpp"

#include <fmt/args.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <unistd.h>

#include <chrono>

#include "journal_output.hpp"
#include "lode/sdk/rt_log.hpp"

namespace lode {

LogDrain::LogDrain(EventLog& events, std::chrono::milliseconds pause)
    : events_(events), journal_(cli::is_journal_stream(STDERR_FILENO)) {
  thread_ = std::thread([this, pause] {
    while (running_.load(std::memory_order_relaxed)) {
      drain_once();
      std::unique_lock lock(pause_mutex_);
      pause_.wait_for(lock, pause, [this] { return !running_.load(); });
    }
  });
}

LogDrain::~LogDrain() { stop(); }

void LogDrain::drain_once() {
  LogRecord r;
  auto& ring = rt_log_ring();
  while (ring.pop(r)) {
    fmt::dynamic_format_arg_store<fmt::format_context> args;
    for (std::uint8_t i = 0; i < r.argc && i < r.args.size(); ++i) args.push_back(r.args[i]);
    std::string text;
    try {
      text = fmt::vformat(r.format, args);
    } catch (const fmt::format_error&) {
      text = std::string(r.format) + " (bad log format)";
    }
    if (journal_) {
      // The journal stamps the time and reads the level from the prefix.
      const auto severity = r.level == LogLevel::error  ? cli::Severity::error
                            : r.level == LogLevel::warn ? cli::Severity::warning
                            : r.level == LogLevel::info ? cli::Severity::info
                                                        : cli::Severity::debug;
      cli::say(stderr, severity, "lode: [%s cycle %llu] %s\n", r.source, static_cast<unsigned long long>(r.cycle),
               text.c_str());
    } else {
      const auto level = r.level == LogLevel::error  ? spdlog::level::err
                         : r.level == LogLevel::warn ? spdlog::level::warn
                         : r.level == LogLevel::info ? spdlog::level::info
                                                     : spdlog::level::debug;
      spdlog::log(level, "[{} cycle {}] {}", r.source, r.cycle, text);
    }
    if (r.level >= LogLevel::warn)
      events_.post(r.time_ns, r.cycle, r.level == LogLevel::error ? "error" : "warning",
                   std::string(r.source) + ": " + text);
  }
  const auto dropped = ring.dropped();
  if (dropped > reported_drops_) {
    events_.post(0, 0, "warning",
                 "RT log ring full: " + std::to_string(dropped - reported_drops_) + " records dropped");
    reported_drops_ = dropped;
  }
}

void LogDrain::stop() {
  {
    // Under the mutex: the thread either has not yet checked running_ (and will not wait) or
    // is waiting (and is woken).
    std::lock_guard lock(pause_mutex_);
    if (!running_.exchange(false)) return;
  }
  pause_.notify_one();
  if (thread_.joinable()) thread_.join();
  drain_once();
}

}  // namespace lode
