// The `telemetry:` section of a pipeline file: domain, transport, what is published at which
// rate, QoS, commands and their allow-lists, DDS Security files. Parsed once the blocks are
// bound (it names signals), into the TelemetrySpec the DDS bridge reads.
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
#include "section_params.hpp"

namespace lode {

using namespace pipeline_detail;


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
  auto section = detail::section_params(t, "telemetry", file, diag);
  if (!section) return;
  Params& p = *section;
  TelemetrySpec& spec = telemetry;
  spec.enabled = true;
  const auto domain = p.integer("domain", 0);
  p.check(domain >= 0 && domain <= 232, "domain", "DDS domain id must be in 0..232, got " + std::to_string(domain));
  spec.domain = static_cast<int>(domain);
  const auto transport = p.choice("transport", {"loopback", "shm", "udp_loopback", "network"}, "loopback");
  spec.transport.kind = transport_kind_from(transport).value_or(TransportSpec::Kind::loopback);
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
          "must be in [0.05, 100] ms (the longest the publisher waits for the RT thread's doorbell)");
  spec.timing_rate_hz = p.number("timing_rate_hz", 1.0);
  p.check(spec.timing_rate_hz > 0 && spec.timing_rate_hz <= 100, "timing_rate_hz", "must be in (0, 100] Hz");
  const auto ring = p.integer("ring_records", 0);
  p.check(ring >= 0 && ring <= (1 << 24), "ring_records", "must be in 0..16777216 (0 = one second of samples)");
  spec.ring_records = static_cast<std::uint32_t>(std::clamp<std::int64_t>(ring, 0, 1 << 24));
  // A real-time loop's publisher runs SCHED_FIFO just above normal threads: measured at 10 kHz
  // on a 2-vCPU VM, capture to subscriber p99 111 to 145 us against 167 to 1916 us with normal
  // scheduling, in alternating runs.
  const int rt_priority = realtime.priority;
  const int default_priority = rt_priority > 1 ? std::min(kDefaultPublisherPriority, rt_priority - 1) : 0;
  const auto priority = p.integer("priority", default_priority);
  p.check(priority >= 0 && priority <= 98, "priority",
          "must be in 0..98 (a SCHED_FIFO priority for the publisher thread; 0 = normal scheduling)");
  if (priority > 0 && rt_priority > 0)
    p.check(priority < rt_priority, "priority",
            "must be below realtime.priority (" + std::to_string(rt_priority) +
                "): the RT thread must preempt the publisher, never wait for it");
  spec.publisher_priority = static_cast<int>(std::clamp<std::int64_t>(priority, 0, 98));
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


}  // namespace lode
