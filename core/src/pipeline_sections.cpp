// Pipeline::Impl: the sections of a pipeline file that set up how it runs rather than what
// it computes: realtime:, record:, monitor: and envelope: (telemetry: is read in
// telemetry_config.cpp, health: in health_monitor.cpp). Each is parsed once the blocks are
// bound (they name signals and blocks), into plain settings the runner and the cycle read.
#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/telemetry.hpp"
#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"

namespace lode {

using namespace pipeline_detail;

void Pipeline::Impl::parse_record(const YAML::Node& node) {
  if (!node.IsMap()) {
    error(detail::location_of(node, file), "record", "expected a map");
    return;
  }
  Params p = detail::make_params(node, "record", file, diag);
  record_settings.flush_interval_s = p.number("flush_interval_s", 1.0);
  p.check(record_settings.flush_interval_s >= 0.05 && record_settings.flush_interval_s <= 60.0, "flush_interval_s",
          "must be 0.05..60 s (how much of the run a crash may lose)");
  record_settings.stop_on_error = p.choice("on_error", {"continue", "stop"}, "continue") == "stop";
  detail::report_unread_keys(p);
}

void Pipeline::Impl::parse_realtime(const YAML::Node& rt) {
  if (!rt.IsMap()) {
    error(detail::location_of(rt, file), "realtime", "expected a map");
    return;
  }
  Params p = detail::make_params(rt, "realtime", file, diag);
  // Range-checked as read, before narrowing to int: 4294967376 must not become 80.
  const std::int64_t priority = p.integer("priority", 0);
  p.check(priority >= 0 && priority <= 99, "priority",
          "SCHED_FIFO priority must be 0 (none) or 1..99, got " + std::to_string(priority));
  realtime.priority = priority >= 0 && priority <= 99 ? static_cast<int>(priority) : 0;
  const std::int64_t cpu = p.integer("cpu", -1);
  p.check(cpu >= -1 && cpu < 1024, "cpu", "cpu must be -1 (any) or a CPU index, got " + std::to_string(cpu));
  realtime.cpu = cpu >= -1 && cpu < 1024 ? static_cast<int>(cpu) : -1;
  realtime.lock_memory = p.flag("lock_memory", false);
  const auto policy = p.choice("overrun_policy", {"skip", "catch_up", "stop"}, "skip");
  realtime.overrun_policy = policy == "stop"       ? OverrunPolicy::stop
                            : policy == "catch_up" ? OverrunPolicy::catch_up
                                                   : OverrunPolicy::skip;
  const auto max_over = p.integer("max_overruns", 0);
  p.check(max_over >= 0, "max_overruns", "must be >= 0");
  realtime.max_overruns = static_cast<std::uint64_t>(std::max<std::int64_t>(0, max_over));
  realtime.spin_us = p.integer("spin_us", 0);
  p.check(realtime.spin_us >= 0 && realtime.spin_us <= 1'000'000, "spin_us",
          "busy-wait before each deadline must be 0..1000000 us, got " + std::to_string(realtime.spin_us));
  realtime.real_clock = p.choice("clock", {"sim", "real"}, "sim") == "real";
  detail::report_unread_keys(p);
}

void Pipeline::Impl::parse_monitor(const YAML::Node& m) {
  if (!m) return;
  if (!m.IsMap()) {
    error(detail::location_of(m, file), "monitor", "expected a map");
    return;
  }
  Params p = detail::make_params(m, "monitor", file, diag);
  auto ref = [&](const char* key) -> std::optional<SignalRef> {
    if (!p.has(key)) {
      p.text(key, "");
      return std::nullopt;
    }
    const auto name_ref = p.text(key);
    auto s = signal(name_ref);
    if (!s) p.fail(key, "no output '" + name_ref + "' (expected block.port)");
    return s;
  };
  monitor.show = ref("show");
  monitor.estimate = ref("estimate");
  monitor.truth = ref("truth");
  monitor.reference = ref("reference");
  for (const auto& r : p.texts("record", {})) {
    auto s = signal(r);
    if (!s) p.fail("record", "no output '" + r + "' (expected block.port)");
    else monitor.record.push_back(*s);
  }
  const auto hold = p.numbers("hold_s", {0.0, 0.0}, 2);
  monitor.hold_start_s = hold[0];
  monitor.hold_end_s = hold[1];
  p.check(hold[1] >= hold[0] && hold[0] >= 0, "hold_s", "expected [start, end] with 0 <= start <= end");
  monitor.settle_band = p.number("settle_band", 0.02);
  p.check(monitor.settle_band > 0 && monitor.settle_band < 1, "settle_band", "must be in (0, 1)");
  const std::size_t n = monitor.truth ? monitor.truth->size() : 0;
  if (monitor.truth && monitor.estimate && monitor.estimate->size() != n)
    p.fail("estimate", "must have as many elements as `truth` (" + std::to_string(n) + ")");
  if (monitor.truth && monitor.reference && monitor.reference->size() != n)
    p.fail("reference", "must have as many elements as `truth` (" + std::to_string(n) + ")");
  detail::report_unread_keys(p);
}

void Pipeline::Impl::parse_envelope(const YAML::Node& node) {
  envelope_at = ops.size();
  for (std::size_t i = 0; i < ops.size(); ++i)
    if (ops[i].write_phase) {
      envelope_at = i;
      break;
    }
  if (!node) return;
  if (!node.IsMap()) {
    error(detail::location_of(node, file), "envelope",
          "expected a map `<block>.<port>: {max_abs: [...], max_rate: [...], max_invalid_s: ...}`");
    return;
  }
  const double inf = std::numeric_limits<double>::infinity();
  for (const auto& kv : node) {
    const std::string ref = kv.first.Scalar();
    const std::string path = "envelope." + ref;
    const auto s = signal(ref);
    if (!s) {
      error(detail::location_of(kv.first, file), path, "no output '" + ref + "' (expected block.port)");
      continue;
    }
    if (!kv.second.IsMap()) {
      error(detail::location_of(kv.second, file), path, "expected a map (min, max, max_abs, max_rate, max_invalid_s)");
      continue;
    }
    Params p = detail::make_params(kv.second, path, file, diag);
    const std::size_t n = s->size();
    Envelope::Limit limit;
    limit.signal = ref;
    limit.data = s->data;
    limit.elements = s->elements;
    limit.min = p.numbers("min", std::vector<double>(n, -inf), n);
    limit.max = p.numbers("max", std::vector<double>(n, inf), n);
    const auto max_abs = p.numbers("max_abs", std::vector<double>(n, inf), n);
    limit.max_rate = p.numbers("max_rate", std::vector<double>(n, inf), n);
    for (std::size_t i = 0; i < n && i < max_abs.size() && i < limit.min.size() && i < limit.max.size(); ++i) {
      p.check(max_abs[i] > 0, "max_abs", "every max_abs must be > 0");
      limit.min[i] = std::max(limit.min[i], -max_abs[i]);
      limit.max[i] = std::min(limit.max[i], max_abs[i]);
      p.check(limit.min[i] < limit.max[i], "max", "every element's range must be non-empty (min < max)");
    }
    for (double r : limit.max_rate) p.check(r > 0, "max_rate", "every max_rate must be > 0 (units per second)");
    if (p.has("max_invalid_s")) {
      const double s_invalid = p.number("max_invalid_s");
      p.check(s_invalid >= 0 && s_invalid <= 3600, "max_invalid_s", "must be 0..3600 s");
      limit.max_invalid_ns = std::llround(std::clamp(s_invalid, 0.0, 3600.0) * 1e9);
    }
    const bool limits_something = p.has("min") || p.has("max") || p.has("max_abs") || p.has("max_rate") ||
                                  p.has("max_invalid_s");
    if (!limits_something) p.fail("an envelope entry must set min, max, max_abs, max_rate or max_invalid_s");
    detail::report_unread_keys(p);
    if (p.ok()) envelope.add(std::move(limit));
  }
}

// --------------------------------------------------------------------------------------

Pipeline::Pipeline() : impl_(std::make_unique<Impl>()) {}

Pipeline::~Pipeline() {
  if (impl_ && impl_->active) deactivate();
  // Blocks own their models; both are destroyed here, while their libraries stay loaded.
}

}  // namespace lode
