#include "lode/event_log.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <utility>

namespace lode {

std::string bounded_text(std::string text, std::size_t max_bytes) {
  if (text.size() <= max_bytes) return text;
  const std::size_t original = text.size();
  std::string note = "...[cut " + std::to_string(original) + " bytes]";
  std::size_t keep = max_bytes > note.size() ? max_bytes - note.size() : 0;
  // Do not split a UTF-8 sequence: back up over continuation bytes (10xxxxxx).
  while (keep > 0 && (static_cast<unsigned char>(text[keep]) & 0xC0) == 0x80) --keep;
  text.resize(keep);
  note = "...[cut " + std::to_string(original - keep) + " bytes]";
  return text + note;
}

void EventLog::post(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text) {
  kind = bounded_text(std::move(kind), kMaxKindBytes);
  text = bounded_text(std::move(text), kMaxTextBytes);
  spdlog::debug("event [{}] cycle {}: {}", kind, cycle, text);
  std::lock_guard lock(mutex_);
  ++posted_;
  if (head_.size() < kKeptHead) {
    head_.push_back({time_ns, cycle, std::move(kind), std::move(text)});
    return;
  }
  tail_.push_back({time_ns, cycle, std::move(kind), std::move(text)});
  if (tail_.size() > kKeptTail) {
    tail_.pop_front();
    ++dropped_;
  }
}

void EventLog::post_limited(std::int64_t time_ns, std::uint64_t cycle, std::string kind, std::string text) {
  kind = bounded_text(std::move(kind), kMaxKindBytes);
  const std::int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::steady_clock::now().time_since_epoch())
                               .count();
  std::uint64_t held_back = 0;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(limiters_.begin(), limiters_.end(), [&](const Limiter& l) { return l.kind == kind; });
    if (it == limiters_.end()) {
      limiters_.push_back({kind, now, 0, 0});
      it = limiters_.end() - 1;
    }
    if (now - it->window_start_ns >= 1'000'000'000) {
      it->window_start_ns = now;
      it->in_window = 0;
    }
    if (it->in_window >= kLimitedPerSecond) {
      ++it->held_back;
      ++suppressed_;
      return;
    }
    ++it->in_window;
    held_back = std::exchange(it->held_back, 0);
  }
  if (held_back > 0) text = "(" + std::to_string(held_back) + " more '" + kind + "' events suppressed before this one) " + text;
  post(time_ns, cycle, std::move(kind), std::move(text));
}

std::uint64_t EventLog::suppressed() const {
  std::lock_guard lock(mutex_);
  return suppressed_;
}

std::vector<Event> EventLog::snapshot() const {
  std::lock_guard lock(mutex_);
  std::vector<Event> out(head_.begin(), head_.end());
  out.insert(out.end(), tail_.begin(), tail_.end());
  return out;
}

std::vector<Event> EventLog::since(std::size_t& cursor) const {
  std::lock_guard lock(mutex_);
  std::vector<Event> out;
  // Event number k (0-based, in posting order) is head_[k] for k < head size, else
  // tail_[k - head size - dropped_] while it is kept.
  const std::uint64_t first_tail = head_.size() + dropped_;
  for (std::uint64_t k = cursor; k < head_.size() && k < posted_; ++k) out.push_back(head_[k]);
  std::uint64_t k = std::max<std::uint64_t>(cursor, head_.size());
  if (k < first_tail) {
    const Event& next = tail_.empty() ? head_.back() : tail_.front();
    out.push_back({next.time_ns, next.cycle, "dropped",
                   std::to_string(first_tail - k) + " events were posted faster than they were read and are lost"});
    k = first_tail;
  }
  for (; k < posted_; ++k) out.push_back(tail_[k - first_tail]);
  cursor = posted_;
  return out;
}

std::uint64_t EventLog::posted() const {
  std::lock_guard lock(mutex_);
  return posted_;
}

std::uint64_t EventLog::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
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
