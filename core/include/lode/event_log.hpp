// The event log: faults, start/stop, degraded RT settings, dropped log records.
// Non-RT only (the RT thread reports through rt_log(), whose warnings the drainer forwards).
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "lode/json.hpp"

namespace lode {

struct Event {
  std::int64_t time_ns = 0;
  std::uint64_t cycle = 0;
  std::string kind;  ///< "start", "stop", "fault", "warning", "rt", ...
  std::string text;
};

class EventLog {
 public:
  void post(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text);
  [[nodiscard]] std::vector<Event> snapshot() const;
  /// Events posted since `cursor` (an index into the log); advances the cursor.
  [[nodiscard]] std::vector<Event> since(std::size_t& cursor) const;
  [[nodiscard]] Json to_json() const;

 private:
  mutable std::mutex mutex_;
  std::vector<Event> events_;
};

}  // namespace lode
