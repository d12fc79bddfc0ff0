#include "lode/event_log.hpp"

#include <spdlog/spdlog.h>

namespace lode {

void EventLog::post(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text) {
  spdlog::debug("event [{}] cycle {}: {}", kind, cycle, text);
  std::lock_guard lock(mutex_);
  events_.push_back({time_ns, cycle, std::move(kind), std::move(text)});
}

std::vector<Event> EventLog::snapshot() const {
  std::lock_guard lock(mutex_);
  return events_;
}

std::vector<Event> EventLog::since(std::size_t& cursor) const {
  std::lock_guard lock(mutex_);
  std::vector<Event> out;
  if (cursor < events_.size()) out.assign(events_.begin() + static_cast<std::ptrdiff_t>(cursor), events_.end());
  cursor = events_.size();
  return out;
}

Json EventLog::to_json() const {
  Json out = Json::array();
  for (const auto& e : snapshot()) {
    Json j = Json::object();
    j["time_s"] = static_cast<double>(e.time_ns) * 1e-9;
    j["cycle"] = e.cycle;
    j["kind"] = e.kind;
    j["text"] = e.text;
    out.push(std::move(j));
  }
  return out;
}

}  // namespace lode
