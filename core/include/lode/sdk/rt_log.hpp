// RT-safe logging: fixed-size records into a lock-free ring, formatted off the RT thread.
//
// The RT thread calls rt_log(...) with a *string literal* format (fmt syntax) and up to four
// numbers; the record is copied into a bounded ring (no allocation, no lock, no syscall).
// A non-RT drainer formats the records into spdlog. When the ring is full the record is
// dropped and counted; the drop count is reported by the drainer, never lost silently.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace lode {

enum class LogLevel : std::uint8_t { debug, info, warn, error };

struct LogRecord {
  std::int64_t time_ns = 0;
  std::uint64_t cycle = 0;
  const char* source = "";  ///< static or pipeline-lifetime string (block name)
  const char* format = "";  ///< string literal, fmt syntax, up to 4 "{}"
  std::array<double, 4> args{};
  std::uint8_t argc = 0;
  LogLevel level = LogLevel::info;
};

/// Bounded multi-producer single-consumer queue of LogRecord (Vyukov's bounded queue).
class RtLogRing {
 public:
  static constexpr std::size_t kCapacity = 4096;  // power of two
  RtLogRing();
  /// RT-safe. Returns false (and counts a drop) when full.
  bool push(const LogRecord& record) noexcept;
  /// Consumer side only.
  bool pop(LogRecord& out) noexcept;
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  struct Cell {
    std::atomic<std::size_t> sequence;
    LogRecord record;
  };
  std::array<Cell, kCapacity> cells_;
  alignas(64) std::atomic<std::size_t> enqueue_pos_{0};
  alignas(64) std::atomic<std::size_t> dequeue_pos_{0};
  alignas(64) std::atomic<std::uint64_t> dropped_{0};
};

/// The process-wide ring (one per process; the drainer lives in the runner).
RtLogRing& rt_log_ring() noexcept;

/// The scheduler keeps these current so records carry time and cycle without arguments.
void rt_log_set_clock(std::int64_t time_ns, std::uint64_t cycle) noexcept;
/// The clock last set: the time and cycle of the cycle running or last run, for what is
/// posted off the RT thread about it (a refused command's event).
void rt_log_clock(std::int64_t& time_ns, std::uint64_t& cycle) noexcept;

void rt_log(LogLevel level, const char* source, const char* format) noexcept;
void rt_log(LogLevel level, const char* source, const char* format, double a) noexcept;
void rt_log(LogLevel level, const char* source, const char* format, double a, double b) noexcept;
void rt_log(LogLevel level, const char* source, const char* format, double a, double b,
            double c) noexcept;
void rt_log(LogLevel level, const char* source, const char* format, double a, double b, double c,
            double d) noexcept;

}  // namespace lode
