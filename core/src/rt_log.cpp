#include "lode/sdk/rt_log.hpp"

namespace lode {

RtLogRing::RtLogRing() {
  for (std::size_t i = 0; i < kCapacity; ++i) cells_[i].sequence.store(i, std::memory_order_relaxed);
}

bool RtLogRing::push(const LogRecord& record) noexcept {
  std::size_t pos = enqueue_pos_.load(std::memory_order_relaxed);
  for (;;) {
    Cell& cell = cells_[pos & (kCapacity - 1)];
    const std::size_t seq = cell.sequence.load(std::memory_order_acquire);
    const auto diff = static_cast<std::ptrdiff_t>(seq) - static_cast<std::ptrdiff_t>(pos);
    if (diff == 0) {
      if (enqueue_pos_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) {
        cell.record = record;
        cell.sequence.store(pos + 1, std::memory_order_release);
        return true;
      }
    } else if (diff < 0) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    } else {
      pos = enqueue_pos_.load(std::memory_order_relaxed);
    }
  }
}

bool RtLogRing::pop(LogRecord& out) noexcept {
  std::size_t pos = dequeue_pos_.load(std::memory_order_relaxed);
  Cell& cell = cells_[pos & (kCapacity - 1)];
  const std::size_t seq = cell.sequence.load(std::memory_order_acquire);
  if (static_cast<std::ptrdiff_t>(seq) - static_cast<std::ptrdiff_t>(pos + 1) < 0) return false;
  out = cell.record;
  dequeue_pos_.store(pos + 1, std::memory_order_relaxed);
  cell.sequence.store(pos + kCapacity, std::memory_order_release);
  return true;
}

RtLogRing& rt_log_ring() noexcept {
  static RtLogRing ring;
  return ring;
}

namespace {
std::atomic<std::int64_t> g_time_ns{0};
std::atomic<std::uint64_t> g_cycle{0};

void emit(LogLevel level, const char* source, const char* format, std::uint8_t argc, double a,
          double b, double c, double d) noexcept {
  LogRecord r;
  r.time_ns = g_time_ns.load(std::memory_order_relaxed);
  r.cycle = g_cycle.load(std::memory_order_relaxed);
  r.source = source;
  r.format = format;
  r.args = {a, b, c, d};
  r.argc = argc;
  r.level = level;
  rt_log_ring().push(r);
}
}  // namespace

void rt_log_set_clock(std::int64_t time_ns, std::uint64_t cycle) noexcept {
  g_time_ns.store(time_ns, std::memory_order_relaxed);
  g_cycle.store(cycle, std::memory_order_relaxed);
}

void rt_log_clock(std::int64_t& time_ns, std::uint64_t& cycle) noexcept {
  time_ns = g_time_ns.load(std::memory_order_relaxed);
  cycle = g_cycle.load(std::memory_order_relaxed);
}

void rt_log(LogLevel level, const char* source, const char* format) noexcept {
  emit(level, source, format, 0, 0, 0, 0, 0);
}
void rt_log(LogLevel level, const char* source, const char* format, double a) noexcept {
  emit(level, source, format, 1, a, 0, 0, 0);
}
void rt_log(LogLevel level, const char* source, const char* format, double a, double b) noexcept {
  emit(level, source, format, 2, a, b, 0, 0);
}
void rt_log(LogLevel level, const char* source, const char* format, double a, double b,
            double c) noexcept {
  emit(level, source, format, 3, a, b, c, 0);
}
void rt_log(LogLevel level, const char* source, const char* format, double a, double b, double c,
            double d) noexcept {
  emit(level, source, format, 4, a, b, c, d);
}

}  // namespace lode
