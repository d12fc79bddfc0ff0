#include "lode/sdk/clock.hpp"
#include "lode/telemetry.hpp"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>

namespace lode {

const char* to_string(TransportSpec::Kind kind) {
  switch (kind) {
    case TransportSpec::Kind::loopback: return "loopback";
    case TransportSpec::Kind::shm: return "shm";
    case TransportSpec::Kind::udp_loopback: return "udp_loopback";
    case TransportSpec::Kind::network: return "network";
  }
  return "?";
}

std::optional<TransportSpec::Kind> transport_kind_from(std::string_view name) {
  for (const auto kind : {TransportSpec::Kind::loopback, TransportSpec::Kind::shm, TransportSpec::Kind::udp_loopback,
                          TransportSpec::Kind::network})
    if (name == to_string(kind)) return kind;
  return std::nullopt;
}

std::string signal_topic(const std::string& pipeline, const std::string& block, const std::string& port) {
  return "lode/" + pipeline + "/" + block + "/" + port;
}

std::string pipeline_topic(const std::string& pipeline, const std::string& what) {
  return "lode/" + pipeline + "/" + what;
}

namespace {
std::size_t ring_capacity(const TelemetrySpec& spec, double rate_hz) {
  if (spec.ring_records > 0) return spec.ring_records;
  // One second of samples, at least 1024: the publisher drains every millisecond, so the
  // ring only fills when the publisher thread itself is starved for that long.
  return std::max<std::size_t>(1024, static_cast<std::size_t>(rate_hz) + 1);
}

}  // namespace

namespace {
long futex(std::atomic<std::uint32_t>& word, int op, std::uint32_t value, const timespec* timeout) noexcept {
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t), "a futex is a plain 32-bit word");
  return syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), op, value, timeout, nullptr, 0);
}
}  // namespace

void PublishDoorbell::ring() noexcept {
  // Sequentially consistent on both sides (Dekker): either the waiter sees the new sequence
  // before it sleeps, or this sees its `sleeping_` and wakes it; FUTEX_WAIT re-checks the
  // word in the kernel, so a ring between its check and its sleep is not lost either.
  // Only the waiter clears `sleeping_`: a ring that cleared it could clear the flag of the
  // waiter's next wait(), whose sleep no later ring would then end.
  sequence_.fetch_add(1, std::memory_order_seq_cst);
  if (sleeping_.load(std::memory_order_seq_cst) != 0) {
    const std::int64_t start = monotonic_ns();
    futex(sequence_, FUTEX_WAKE_PRIVATE, 1, nullptr);
    const std::int64_t spent = monotonic_ns() - start;
    wakes_.store(wakes_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    wake_ns_.store(wake_ns_.load(std::memory_order_relaxed) + static_cast<std::uint64_t>(std::max<std::int64_t>(spent, 0)),
                   std::memory_order_relaxed);
  }
}

bool PublishDoorbell::wait(std::uint32_t seen, std::chrono::nanoseconds timeout) noexcept {
  if (timeout.count() <= 0) return false;
  sleeping_.store(1, std::memory_order_seq_cst);
  if (sequence_.load(std::memory_order_seq_cst) != seen) {
    sleeping_.store(0, std::memory_order_relaxed);
    return true;
  }
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(timeout.count() / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(timeout.count() % 1'000'000'000);
  const long r = futex(sequence_, FUTEX_WAIT_PRIVATE, seen, &ts);
  const bool timed_out = r != 0 && errno == ETIMEDOUT;
  sleeping_.store(0, std::memory_order_relaxed);
  return !timed_out;
}

void PublishDoorbell::wake_all() noexcept {
  sleeping_.store(0, std::memory_order_seq_cst);
  futex(sequence_, FUTEX_WAKE_PRIVATE, INT_MAX, nullptr);
}

TelemetryTap::TelemetryTap(const TelemetrySpec& spec, double pipeline_rate_hz) {
  for (const auto& s : spec.signals) {
    Channel c;
    c.data = s.signal.data;
    c.width = s.signal.size();
    c.decimation = std::max<std::uint32_t>(1, s.decimation);
    c.ring = std::make_unique<SampleRing>(c.width, ring_capacity(spec, pipeline_rate_hz / c.decimation));
    channels_.push_back(std::move(c));
  }
  if (spec.state) {
    Channel c;
    c.data = spec.state->pose.data;
    c.width = spec.state->pose.size();
    if (spec.state->twist) {
      c.extra_data[0] = spec.state->twist->data;
      c.extra_width[0] = spec.state->twist->size();
    }
    if (spec.state->covariance) {
      c.extra_data[1] = spec.state->covariance->data;
      c.extra_width[1] = spec.state->covariance->size();
    }
    c.decimation = std::max<std::uint32_t>(1, spec.state->decimation);
    c.ring = std::make_unique<SampleRing>(c.width + c.extra_width[0] + c.extra_width[1],
                                          ring_capacity(spec, pipeline_rate_hz / c.decimation));
    channels_.push_back(std::move(c));
  }
}

void TelemetryTap::after_cycle(const Tick& tick) noexcept {
  SampleHeader h;
  h.cycle = tick.cycle;
  h.stamp_ns = tick.time_ns;
  bool stamped = false;
  for (auto& c : channels_) {
    if (tick.cycle % c.decimation != 0) continue;
    if (!stamped) {
      h.captured_ns = monotonic_ns();
      stamped = true;
    }
    c.ring->push(h, c.data, c.width, c.extra_data[0], c.extra_width[0], c.extra_data[1], c.extra_width[1]);
  }
  offered_this_cycle_ = offered_this_cycle_ || stamped;
}

void TelemetryTap::cycle_finished() noexcept {
  if (!offered_this_cycle_) return;  // a decimated cycle: nothing new to publish
  offered_this_cycle_ = false;
  doorbell_.ring();
}

std::uint64_t TelemetryTap::dropped() const {
  std::uint64_t n = 0;
  for (const auto& c : channels_) n += c.ring->dropped();
  return n;
}

std::uint64_t TelemetryTap::offered() const {
  std::uint64_t n = 0;
  for (const auto& c : channels_) n += c.ring->pushed() + c.ring->dropped();
  return n;
}

}  // namespace lode
