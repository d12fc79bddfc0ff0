#include "lode/sdk/clock.hpp"
#include "lode/telemetry.hpp"

#include <time.h>

#include <algorithm>

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
