// Pipeline::Impl: the sections of a pipeline file that set up how it runs rather than what
// it computes: realtime:, record:, monitor:, telemetry:, envelope: and health:. Each is
// parsed once the blocks are bound (they name signals and blocks), into plain settings the
// runner and the cycle read.
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
#include "lode/units.hpp"
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

namespace {
bool valid_ipv4(const std::string& text) {
  in_addr a{};
  return inet_pton(AF_INET, text.c_str(), &a) == 1;
}

/// "10.0.0.2" or "10.0.0.2:7412".
bool valid_peer(const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) return valid_ipv4(text);
  const std::string port = text.substr(colon + 1);
  if (port.empty() || port.size() > 5 || !std::all_of(port.begin(), port.end(), ::isdigit)) return false;
  return valid_ipv4(text.substr(0, colon)) && std::stoi(port) <= 65535;
}

std::string resolve_relative(const std::string& path, const std::string& config_file) {
  if (path.empty() || path[0] == '/') return path;
  const auto slash = config_file.rfind('/');
  return slash == std::string::npos ? path : config_file.substr(0, slash + 1) + path;
}
}  // namespace

void Pipeline::Impl::parse_telemetry(const YAML::Node& t) {
  if (!t) return;
  if (!t.IsMap()) {
    error(detail::location_of(t, file), "telemetry", "expected a map");
    return;
  }
  Params p = detail::make_params(t, "telemetry", file, diag);
  TelemetrySpec& spec = telemetry;
  spec.enabled = true;
  const auto domain = p.integer("domain", 0);
  p.check(domain >= 0 && domain <= 232, "domain", "DDS domain id must be in 0..232, got " + std::to_string(domain));
  spec.domain = static_cast<int>(domain);
  const auto transport = p.choice("transport", {"loopback", "shm", "udp_loopback", "network"}, "loopback");
  spec.transport.kind = transport == "shm"            ? TransportSpec::Kind::shm
                        : transport == "udp_loopback" ? TransportSpec::Kind::udp_loopback
                        : transport == "network"      ? TransportSpec::Kind::network
                                                      : TransportSpec::Kind::loopback;
  if (auto net = p.optional_child("network")) {
    spec.transport.interfaces = net->texts("interfaces", {});
    for (std::size_t i = 0; i < spec.transport.interfaces.size(); ++i)
      net->check(valid_ipv4(spec.transport.interfaces[i]), "interfaces",
                 "interfaces[" + std::to_string(i) + "] '" + spec.transport.interfaces[i] +
                     "' is not an IPv4 address (give the address of the NIC, e.g. 192.168.10.5)");
    spec.transport.initial_peers = net->texts("initial_peers", {});
    for (std::size_t i = 0; i < spec.transport.initial_peers.size(); ++i)
      net->check(valid_peer(spec.transport.initial_peers[i]), "initial_peers",
                 "initial_peers[" + std::to_string(i) + "] '" + spec.transport.initial_peers[i] +
                     "' is not an IPv4 address or address:port");
    spec.transport.multicast = net->flag("multicast", true);
    if (spec.transport.kind != TransportSpec::Kind::network)
      net->fail("`network:` settings only apply with `transport: network` (now '" + transport + "')");
  }

  // Decimation: a published rate must divide the pipeline rate exactly, so every sample is
  // a cycle's value and not an interpolation.
  auto decimation_for = [&](Params& where, const std::string& key, double rate) -> std::uint32_t {
    if (!(rate > 0) || rate > rate_hz * (1 + 1e-12)) {
      where.fail(key, "rate " + std::to_string(rate) + " Hz must be in (0, " + std::to_string(rate_hz) +
                          "] (the pipeline rate)");
      return 1;
    }
    const double n = rate_hz / rate;
    const double rounded = std::round(n);
    if (std::abs(n - rounded) > 1e-9 * n) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "rate %g Hz does not divide the pipeline rate %g Hz; nearest rates: %g or %g Hz", rate,
                    rate_hz, rate_hz / std::ceil(n), rate_hz / std::max(1.0, std::floor(n)));
      where.fail(key, buf);
      return 1;
    }
    return static_cast<std::uint32_t>(rounded);
  };
  const double default_rate = p.number("rate_hz", std::min(rate_hz, 100.0));
  const std::uint32_t default_decimation = decimation_for(p, "rate_hz", default_rate);

  std::map<std::string, double> rates;
  if (auto r = p.optional_child("rates_hz"))
    for (const auto& key : r->keys()) rates[key] = r->number(key);
  for (const auto& ref : p.texts("publish", {})) {
    auto s = signal(ref);
    if (!s) {
      p.fail("publish", "no output '" + ref + "' (expected block.port; `lode describe` lists every output)");
      continue;
    }
    bool duplicate = false;
    for (const auto& existing : spec.signals) duplicate = duplicate || existing.signal.data == s->data;
    if (duplicate) {
      p.fail("publish", "'" + ref + "' is listed twice");
      continue;
    }
    TelemetrySignal ts;
    ts.signal = *s;
    ts.topic = signal_topic(name, s->block, s->port);
    ts.decimation = default_decimation;
    if (auto it = rates.find(ref); it != rates.end()) {
      ts.decimation = decimation_for(p, "rates_hz", it->second);
      rates.erase(it);
    }
    spec.signals.push_back(std::move(ts));
  }
  for (const auto& [ref, rate] : rates)
    p.fail("rates_hz", "'" + ref + "' has a rate but is not in `publish`");

  if (auto st = p.optional_child("state")) {
    auto ref = [&](const char* key, bool required) -> std::optional<SignalRef> {
      if (!required && !st->has(key)) return std::nullopt;
      const auto text = st->text(key);
      auto s = signal(text);
      if (!s && !text.empty()) st->fail(key, "no output '" + text + "' (expected block.port)");
      return s;
    };
    auto pose = ref("pose", true);
    auto twist = ref("twist", false);
    auto covariance = ref("covariance", false);
    const double state_rate = st->number("rate_hz", default_rate);
    const auto decimation = decimation_for(*st, "rate_hz", state_rate);
    if (pose) {
      StateSpec state;
      state.pose = *pose;
      state.twist = twist;
      state.covariance = covariance;
      state.decimation = decimation;
      state.topic = pipeline_topic(name, "state");
      if (covariance) {
        const std::size_t n_pose = pose->size();
        const std::size_t n_all = n_pose + (twist ? twist->size() : 0);
        const std::size_t c = covariance->size();
        st->check(c == n_pose * n_pose || c == n_all * n_all, "covariance",
                  "'" + covariance->name() + "' has " + std::to_string(c) + " elements; a covariance of the pose (" +
                      std::to_string(n_pose) + "x" + std::to_string(n_pose) + ")" +
                      (twist ? " or of pose and twist (" + std::to_string(n_all) + "x" + std::to_string(n_all) + ")" : "") +
                      " is expected");
      }
      spec.state = std::move(state);
    }
  }
  spec.reliable = p.choice("reliability", {"best_effort", "reliable"}, "best_effort") == "reliable";
  spec.publish_period_s = p.number("publish_period_ms", 1.0) * 1e-3;
  p.check(spec.publish_period_s >= 50e-6 && spec.publish_period_s <= 0.1, "publish_period_ms",
          "must be in [0.05, 100] ms (the publisher's polling period: latency vs CPU)");
  spec.timing_rate_hz = p.number("timing_rate_hz", 1.0);
  p.check(spec.timing_rate_hz > 0 && spec.timing_rate_hz <= 100, "timing_rate_hz", "must be in (0, 100] Hz");
  const auto ring = p.integer("ring_records", 0);
  p.check(ring >= 0 && ring <= (1 << 24), "ring_records", "must be in 0..16777216 (0 = one second of samples)");
  spec.ring_records = static_cast<std::uint32_t>(std::clamp<std::int64_t>(ring, 0, 1 << 24));
  const auto history = p.integer("history", 0);
  p.check(history >= 0 && history <= (1 << 20), "history", "must be in 0..1048576 (0 = one second of samples)");
  spec.history = static_cast<std::uint32_t>(std::clamp<std::int64_t>(history, 0, 1 << 20));

  if (auto c = p.optional_child("commands")) {
    spec.commands.enabled = c->flag("enabled", false);
    spec.commands.allow_hosts = c->texts("allow_hosts", {});
    for (std::size_t i = 0; i < spec.commands.allow_hosts.size(); ++i)
      c->check(valid_ipv4(spec.commands.allow_hosts[i]), "allow_hosts",
               "allow_hosts[" + std::to_string(i) + "] '" + spec.commands.allow_hosts[i] + "' is not an IPv4 address");
    spec.commands.allow_participants = c->texts("allow_participants", {});
  }
  if (auto sec = p.optional_child("security")) {
    auto path = [&](const char* key, bool required) {
      const std::string v = required ? sec->text(key) : sec->text(key, "");
      const std::string resolved = resolve_relative(v, file);
      if (!resolved.empty()) {
        std::ifstream f(resolved);
        sec->check(static_cast<bool>(f), key, "cannot read '" + resolved + "'");
      }
      return resolved;
    };
    spec.security.ca_certificate = path("ca_certificate", true);
    spec.security.certificate = path("certificate", true);
    spec.security.private_key = path("private_key", true);
    spec.security.permissions_ca = path("permissions_ca", false);
    if (spec.security.permissions_ca.empty()) spec.security.permissions_ca = spec.security.ca_certificate;
    spec.security.governance = path("governance", true);
    spec.security.permissions = path("permissions", true);
  }
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

void Pipeline::Impl::parse_health(const YAML::Node& h) {
  if (!h) return;
  if (!h.IsMap()) {
    error(detail::location_of(h, file), "health", "expected a map `<block>: {fallback: ..., ...}`");
    return;
  }
  for (const auto& kv : h) {
    const std::string block_name = kv.first.as<std::string>();
    const std::string path = "health." + block_name;
    const SourceLocation where = detail::location_of(kv.first, file);
    BlockEntry* b = find_block(block_name);
    if (!b) {
      error(where, path, "no block named '" + block_name + "'");
      continue;
    }
    if (b->family < 0 || b->family_role != 0) {
      error(where, path, "'" + block_name + "' is " + (b->is_io() ? "an io block" : !b->shadow_of.empty() ? "a shadow" : "not a block that steps") +
                             "; the health monitor watches estimators and other non-io blocks of the cycle");
      continue;
    }
    if (!kv.second.IsMap()) {
      error(detail::location_of(kv.second, file), path, "expected a map (fallback, non_finite, ...)");
      continue;
    }
    Family& f = families[static_cast<std::size_t>(b->family)];
    Params p = detail::make_params(kv.second, path, file, diag);
    HealthSpec& spec = f.health;
    spec.enabled = true;
    spec.non_finite = p.flag("non_finite", true);
    const auto every = p.integer("covariance_check_every", 1);
    p.check(every >= 0 && every <= 1000000, "covariance_check_every", "must be in 0..1000000 cycles (0 = off)");
    spec.covariance_every = static_cast<std::uint32_t>(std::clamp<std::int64_t>(every, 0, 1000000));
    if (spec.covariance_every > 0 && b->layout.covariance) {
      f.state_values.assign(b->layout.size(), 0.0);
      f.state_covariance.assign(b->layout.size() * b->layout.size(), 0.0);
    }
    const auto window = p.integer("nis_window", 0);
    p.check(window >= 0 && window <= 1000000, "nis_window", "must be in 0..1000000 cycles (0 = off)");
    spec.nis_window = static_cast<std::uint32_t>(std::clamp<std::int64_t>(window, 0, 1000000));
    const std::size_t m = b->block->innovation_size();
    if (spec.nis_window > 0 && m == 0)
      p.fail("nis_window", "plugin " + b->plugin_name + " reports no innovation (innovation_size() = 0): no NIS test possible");
    const double probability = p.number("nis_false_alarm", 1e-6);
    p.check(probability > 0 && probability < 0.5, "nis_false_alarm",
            "must be in (0, 0.5): the chance that a healthy filter trips per window");
    if (p.has("nis_threshold")) {
      spec.nis_threshold = p.number("nis_threshold");
      p.check(spec.nis_threshold > 0, "nis_threshold", "must be > 0 (the window mean of NIS, whose expectation is the channel count)");
    } else if (spec.nis_window > 0 && m > 0) {
      // The window mean of NIS is chi-square with W m degrees of freedom divided by W (white,
      // consistent innovations). Wilson-Hilferty: chi2_p(k) ~ k (1 - 2/(9k) + z sqrt(2/(9k)))^3.
      const double k = static_cast<double>(spec.nis_window) * static_cast<double>(m);
      // Upper normal quantile by bisection on erfc (no new dependency, off the RT thread).
      double lo = 0.0, hi = 40.0;
      for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(mid / std::sqrt(2.0)) > probability ? lo : hi) = mid;
      }
      const double z = 0.5 * (lo + hi);
      const double c = 2.0 / (9.0 * k);
      spec.nis_threshold = k * std::pow(1.0 - c + z * std::sqrt(c), 3) / static_cast<double>(spec.nis_window);
    }
    if (spec.nis_window > 0) {
      f.nis_ring.assign(spec.nis_window, 0.0);
      f.nu.assign(std::max<std::size_t>(m, 1), 0.0);
      f.s.assign(f.nu.size(), 0.0);
    }
    const double budget_us = p.number("step_budget_us", 0.0);
    p.check(budget_us >= 0 && budget_us <= 1e6, "step_budget_us", "must be in [0, 1e6] us (0 = off)");
    spec.step_budget_ns = static_cast<std::int64_t>(std::llround(budget_us * 1e3));
    const auto cycles = p.integer("budget_cycles", 3);
    p.check(cycles >= 1 && cycles <= 100000, "budget_cycles", "must be in 1..100000 (consecutive cycles over budget)");
    spec.budget_cycles = static_cast<std::uint32_t>(std::clamp<std::int64_t>(cycles, 1, 100000));
    if (p.has("fallback")) {
      const std::string fb = p.text("fallback");
      int slot = -1;
      for (std::size_t r = 1; r < f.roles.size(); ++r)
        if (f.roles[r]->name == fb) slot = static_cast<int>(r) - 1;
      if (slot < 0) {
        std::string shadows;
        for (std::size_t r = 1; r < f.roles.size(); ++r) shadows += (shadows.empty() ? "" : ", ") + f.roles[r]->name;
        p.fail("fallback", "'" + fb + "' is not a shadow of '" + block_name + "' (declare it with `shadow_of: " + block_name +
                               "`" + (shadows.empty() ? "" : "; its shadows: " + shadows) +
                               "): the fallback must run every cycle to take over in the same cycle");
      } else if (f.roles[static_cast<std::size_t>(slot) + 1]->shadow_decimation != 1) {
        p.fail("fallback", "'" + fb + "' is decimated (shadow_decimation " +
                               std::to_string(f.roles[static_cast<std::size_t>(slot) + 1]->shadow_decimation) +
                               "): a fallback must step every cycle");
      } else {
        spec.fallback_slot = slot;
        const BlockEntry* role = f.roles[static_cast<std::size_t>(slot) + 1];
        for (std::size_t i = 0; i < f.ranges.size(); ++i)
          f.ranges[i].shadow = arena.data() + output_offset(*role, b->outputs[i].name);
      }
    }
    detail::report_unread_keys(p);
  }
}

// --------------------------------------------------------------------------------------

Pipeline::Pipeline() : impl_(std::make_unique<Impl>()) {}

Pipeline::~Pipeline() {
  if (impl_ && impl_->active) deactivate();
  // Blocks own their models; both are destroyed here, while their libraries stay loaded.
}

}  // namespace lode
