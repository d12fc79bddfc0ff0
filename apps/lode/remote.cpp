// The remote side of `lode`: topics, echo, record, set, swap. Each is a DDS participant
// on the domain and transport given by --domain/--transport/--peers/--interfaces (or
// LODE_DDS_* in the environment); see `lode --help`. Commands (set, swap, record
// --remote-start/--remote-stop) first look for the pipeline's local command socket
// (local_control.hpp) and use DDS only when there is none (--local / --dds force one way).
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <algorithm>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "analysis.hpp"
#include "cli.hpp"
#include "local_control.hpp"
#include "lode/dds/client.hpp"
#include "lode/record/hdf5_recorder.hpp"

namespace lode::cli {

namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

/// Participant options: environment first, then the command line.
std::optional<dds::ParticipantOptions> participant_options(const Args& args, const std::string& role) {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  auto o = dds::options_from_environment("lode-" + role + "-" + std::to_string(getpid()) + "@" + host);
  if (args.has("--name")) o.name = args.option("--name");
  if (args.has("--domain")) {
    auto d = number_option(args, "--domain", 0, 0, 232);
    if (!d || *d != std::round(*d)) {
      std::fprintf(stderr, "lode: --domain must be an integer in 0..232\n");
      return std::nullopt;
    }
    o.domain = static_cast<int>(*d);
  }
  if (args.has("--transport")) {
    const auto t = args.option("--transport");
    if (t == "loopback") o.transport.kind = TransportSpec::Kind::loopback;
    else if (t == "shm") o.transport.kind = TransportSpec::Kind::shm;
    else if (t == "udp_loopback") o.transport.kind = TransportSpec::Kind::udp_loopback;
    else if (t == "network") o.transport.kind = TransportSpec::Kind::network;
    else {
      std::fprintf(stderr, "lode: --transport must be loopback, shm, udp_loopback or network, got '%s'\n", t.c_str());
      return std::nullopt;
    }
  }
  if (args.has("--peers")) o.transport.initial_peers = split_list(args.option("--peers"));
  if (args.has("--interfaces")) o.transport.interfaces = split_list(args.option("--interfaces"));
  return o;
}

std::unique_ptr<dds::Client> make_client(const Args& args, const std::string& role) {
  auto options = participant_options(args, role);
  if (!options) return nullptr;
  auto client = dds::Client::create(*options);
  if (!client) {
    std::fprintf(stderr, "lode: %s\n", client.error().c_str());
    return nullptr;
  }
  return std::move(*client);
}

milliseconds wait_option(const Args& args, double fallback_s) {
  auto w = number_option(args, "--wait", fallback_s, 0, 3600);
  return milliseconds(static_cast<long long>(std::llround((w ? *w : fallback_s) * 1e3)));
}

std::string unit_suffix(const std::string& unit) { return unit.empty() || unit == "1" ? "" : "[" + unit + "]"; }

/// Waits for stop conditions shared by echo and record: Ctrl-C, --duration, every followed
/// pipeline having posted its "stop" event (then a short grace for samples in flight).
class StopWatch {
 public:
  StopWatch(double duration_s) : start_(Clock::now()), duration_s_(duration_s) {}
  void pipeline_stopped(const std::string& pipeline) {
    std::lock_guard lock(mutex_);
    stopped_.insert(pipeline);
    if (!stopped_at_) stopped_at_ = Clock::now();
  }
  void follow(const std::string& pipeline) {
    std::lock_guard lock(mutex_);
    followed_.insert(pipeline);
  }
  void done() { done_.store(true); }
  /// Why it is time to stop ("" = not yet).
  std::string reason() {
    if (done_.load()) return "done";
    if (stop_requested().load()) return "interrupted";
    if (duration_s_ > 0 && Clock::now() - start_ > std::chrono::duration<double>(duration_s_)) return "duration";
    std::lock_guard lock(mutex_);
    if (!followed_.empty() && stopped_at_ && Clock::now() - *stopped_at_ > milliseconds(700)) {
      bool all = true;
      for (const auto& p : followed_) all = all && stopped_.count(p);
      if (all) return "pipeline stopped";
    }
    return "";
  }

 private:
  Clock::time_point start_;
  double duration_s_;
  std::atomic<bool> done_{false};
  std::mutex mutex_;
  std::set<std::string> followed_, stopped_;
  std::optional<Clock::time_point> stopped_at_;
};

std::string format_scaled(double v, const std::string& unit) {
  auto [scale, shown] = analysis::display_scale(unit, v);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%+12.4f %-6s", v * scale, shown.c_str());
  return buf;
}

}  // namespace

// ---------------------------------------------------------------------------------------
int cmd_topics(const Args& args) {
  auto client = make_client(args, "topics");
  if (!client) return kExitConfig;
  auto signals = client->signals(wait_option(args, 2.0));
  // Metadata arrives topic by topic: once the first is in, give the rest a moment.
  if (!signals.empty()) {
    std::this_thread::sleep_for(milliseconds(500));
    signals = client->signals(milliseconds(0));
  }
  if (signals.empty()) {
    std::fprintf(stderr, "lode: no lodestone topic seen within the wait (is a pipeline with `telemetry:` running on this domain?)\n");
    return kExitFault;
  }
  const bool json = args.has_flag("--json");
  std::set<std::string> pipelines;
  if (json) std::printf("[\n");
  for (std::size_t i = 0; i < signals.size(); ++i) {
    const auto& s = signals[i];
    pipelines.insert(s.pipeline);
    if (json) {
      std::printf("  {\"topic\": \"%s\", \"pipeline\": \"%s\", \"kind\": \"%s\", \"rate_hz\": %.17g, \"names\": [",
                  s.topic.c_str(), s.pipeline.c_str(), s.kind.c_str(), s.rate_hz);
      for (std::size_t k = 0; k < s.names.size(); ++k)
        std::printf("%s\"%s\"", k ? ", " : "", s.names[k].c_str());
      std::printf("], \"units\": [");
      for (std::size_t k = 0; k < s.units.size(); ++k)
        std::printf("%s\"%s\"", k ? ", " : "", s.units[k].c_str());
      std::printf("]}%s\n", i + 1 < signals.size() ? "," : "");
      continue;
    }
    std::string elements;
    for (std::size_t k = 0; k < s.names.size(); ++k)
      elements += (k ? " " : "") + s.names[k] + unit_suffix(k < s.units.size() ? s.units[k] : "");
    std::printf("%-44s %9.6g Hz  %s\n", s.topic.c_str(), s.rate_hz, elements.c_str());
  }
  if (json) {
    std::printf("]\n");
  } else {
    for (const auto& p : pipelines) {
      std::printf("%-44s events (faults, parameter changes, swaps, start/stop)\n", pipeline_topic(p, "events").c_str());
      std::printf("%-44s timing statistics\n", pipeline_topic(p, "timing").c_str());
    }
  }
  return kExitOk;
}

// ---------------------------------------------------------------------------------------
int cmd_echo(const Args& args) {
  if (args.positional.size() != 1) {
    std::fprintf(stderr, "usage: lode echo TOPIC|BLOCK.PORT|events|timing [--count N] [--duration S] [--table] [--wait S]\n"
                         "                 [--latency] [--quiet]\n");
    return kExitConfig;
  }
  const auto count = number_option(args, "--count", 0, 0, 1e15);
  const auto duration = number_option(args, "--duration", 0, 0, 1e9);
  if (!count || !duration) return kExitConfig;
  auto client = make_client(args, "echo");
  if (!client) return kExitConfig;
  install_stop_handlers();
  StopWatch watch(*duration);
  const std::string what = args.positional[0];
  const bool table = args.has_flag("--table") && isatty(STDOUT_FILENO);
  std::mutex out_mutex;
  std::uint64_t received = 0, gaps = 0, out_of_order = 0;
  std::optional<std::uint64_t> first_cycle, last_cycle;
  std::vector<std::unique_ptr<dds::Subscription>> subs;
  // --latency: capture on the RT thread -> taken by this process (same host: one clock).
  const bool latency = args.has_flag("--latency");
  const bool quiet = args.has_flag("--quiet");
  std::vector<double> latencies_us;
  if (latency) latencies_us.reserve(1 << 20);

  if (what == "events" || what == "timing" || what.ends_with("/events") || what.ends_with("/timing")) {
    const bool events = what.ends_with("events");
    std::string pipeline = what.find('/') != std::string::npos ? what.substr(0, what.rfind('/')) : args.option("--pipeline");
    if (pipeline.rfind("lode/", 0) == 0) pipeline = pipeline.substr(5);
    Expected<std::unique_ptr<dds::Subscription>> sub = Status::error("unreachable");
    // A named pipeline's events end with its "stop" event: then echo is done too.
    if (events && !pipeline.empty()) watch.follow(pipeline);
    if (events) {
      sub = client->subscribe_events(pipeline, [&](const dds::EventSample& e) {
        std::lock_guard lock(out_mutex);
        if (*count > 0 && received >= *count) return;
        std::printf("%-16s cycle %-10llu t %.6f s  [%s] %s\n", e.pipeline.c_str(),
                    static_cast<unsigned long long>(e.cycle), static_cast<double>(e.stamp_ns) * 1e-9,
                    e.kind.c_str(), e.text.c_str());
        std::fflush(stdout);
        if (e.kind == "stop") watch.pipeline_stopped(e.pipeline);
        if (*count > 0 && ++received >= *count) watch.done();
      });
    } else {
      sub = client->subscribe_timing(pipeline, [&](const dds::TimingSample& t) {
        std::lock_guard lock(out_mutex);
        if (*count > 0 && received >= *count) return;
        std::printf("%-16s cycle %-10llu overruns %llu missed %llu dropped %llu  wake p50/p99/max %.1f/%.1f/%.1f us"
                    "  cycle p50/p99/max %.2f/%.2f/%.1f us\n",
                    t.pipeline.c_str(), static_cast<unsigned long long>(t.cycle),
                    static_cast<unsigned long long>(t.overruns), static_cast<unsigned long long>(t.missed_periods),
                    static_cast<unsigned long long>(t.telemetry_dropped), t.wake_latency.p50_us,
                    t.wake_latency.p99_us, t.wake_latency.max_us, t.cycle_time.p50_us, t.cycle_time.p99_us,
                    t.cycle_time.max_us);
        for (const auto& b : t.blocks)
          std::printf("    %-22s p50 %.2f  p99 %.2f  max %.1f us\n", b.name.c_str(), b.p50_us, b.p99_us, b.max_us);
        std::fflush(stdout);
        if (*count > 0 && ++received >= *count) watch.done();
      });
    }
    if (!sub) {
      std::fprintf(stderr, "lode: %s\n", sub.error().c_str());
      return kExitFault;
    }
    subs.push_back(std::move(*sub));
  } else {
    auto meta = client->resolve(what, wait_option(args, 5.0));
    if (!meta) {
      std::fprintf(stderr, "lode: %s\n", meta.error().c_str());
      return kExitFault;
    }
    const dds::SignalMeta m = *meta;
    watch.follow(m.pipeline);
    std::string header = "# " + m.topic + "  " + std::to_string(m.rate_hz) + " Hz\n# cycle t[s]";
    for (std::size_t k = 0; k < m.names.size(); ++k)
      header += " " + m.names[k] + unit_suffix(k < m.units.size() ? m.units[k] : "");
    std::printf("%s\n", header.c_str());
    std::fflush(stdout);
    auto last_table = Clock::now();
    auto sub = client->subscribe(m, [&](const dds::SignalMeta& meta_, const dds::Sample& s) {
      std::lock_guard lock(out_mutex);
      if (*count > 0 && received >= *count) return;  // enough; the rest arrives while unsubscribing
      if (last_cycle) {
        if (s.cycle <= *last_cycle) ++out_of_order;
        else if (s.cycle != *last_cycle + meta_.decimation) gaps += (s.cycle - *last_cycle) / meta_.decimation - 1;
      }
      if (!first_cycle) first_cycle = s.cycle;
      last_cycle = s.cycle;
      ++received;
      if (latency) latencies_us.push_back(static_cast<double>(s.received_ns - s.captured_ns) * 1e-3);
      if (quiet) {
      } else if (table) {
        if (Clock::now() - last_table > milliseconds(100)) {
          last_table = Clock::now();
          std::printf("\033[H\033[2J%s  cycle %llu  t %.4f s  (%llu samples)\n", meta_.topic.c_str(),
                      static_cast<unsigned long long>(s.cycle), static_cast<double>(s.stamp_ns) * 1e-9,
                      static_cast<unsigned long long>(received));
          for (std::size_t k = 0; k < s.values.size(); ++k)
            std::printf("  %-14s %s\n", k < meta_.names.size() ? meta_.names[k].c_str() : "?",
                        format_scaled(s.values[k], k < meta_.units.size() ? meta_.units[k] : "").c_str());
          std::fflush(stdout);
        }
      } else {
        std::printf("%llu %.9f", static_cast<unsigned long long>(s.cycle), static_cast<double>(s.stamp_ns) * 1e-9);
        for (double v : s.values) std::printf(" %.17g", v);
        std::printf("\n");
      }
      if (*count > 0 && received >= *count) watch.done();
    });
    if (!sub) {
      std::fprintf(stderr, "lode: %s\n", sub.error().c_str());
      return kExitFault;
    }
    subs.push_back(std::move(*sub));
    auto ev = client->subscribe_events(m.pipeline, [&](const dds::EventSample& e) {
      if (e.kind == "stop") watch.pipeline_stopped(e.pipeline);
    });
    if (ev) subs.push_back(std::move(*ev));
  }
  std::string why;
  while ((why = watch.reason()).empty()) std::this_thread::sleep_for(milliseconds(20));
  subs.clear();
  std::fflush(stdout);
  std::lock_guard lock(out_mutex);
  if (first_cycle)
    std::fprintf(stderr, "lode echo: %llu samples, cycles %llu..%llu, %llu missing, %llu out of order (%s)\n",
                 static_cast<unsigned long long>(received), static_cast<unsigned long long>(*first_cycle),
                 static_cast<unsigned long long>(*last_cycle), static_cast<unsigned long long>(gaps),
                 static_cast<unsigned long long>(out_of_order), why.c_str());
  else
    std::fprintf(stderr, "lode echo: %llu samples (%s)\n", static_cast<unsigned long long>(received), why.c_str());
  if (latency && !latencies_us.empty()) {
    std::sort(latencies_us.begin(), latencies_us.end());
    auto q = [&](double p) { return latencies_us[static_cast<std::size_t>(p * static_cast<double>(latencies_us.size() - 1))]; };
    std::fprintf(stderr, "lode echo: latency RT capture -> received (us): p50 %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f  (%zu samples)\n",
                 q(0.5), q(0.9), q(0.99), q(0.999), latencies_us.back(), latencies_us.size());
  }
  if (*count > 0 && received < *count) return kExitFault;
  return received > 0 ? kExitOk : kExitFault;
}

// ---------------------------------------------------------------------------------------
int remote_record(const Args& args);

int cmd_record(const Args& args) {
  if (args.has("--remote-start") || args.has_flag("--remote-stop")) return remote_record(args);
  if (args.positional.size() != 1) {
    std::fprintf(stderr, "usage: lode record FILE.h5 [--topics a,b,...] [--duration S] [--wait S]\n");
    return kExitConfig;
  }
  const auto duration = number_option(args, "--duration", 0, 0, 1e9);
  if (!duration) return kExitConfig;
  const std::string path = args.positional[0];
  const auto wanted = split_list(args.option("--topics"));
  auto client = make_client(args, "record");
  if (!client) return kExitConfig;
  auto recorder = record::Recorder::create(path, "lode record");
  if (!recorder) {
    std::fprintf(stderr, "lode: %s\n", recorder.error().c_str());
    return kExitFault;
  }
  auto& rec = **recorder;
  install_stop_handlers();
  StopWatch watch(*duration);

  // Listener threads queue; this thread writes (the recorder is single-threaded).
  struct Row {
    int series;
    dds::Sample sample;
  };
  struct EventRow {
    dds::EventSample event;
  };
  std::mutex queue_mutex;
  std::deque<Row> rows;
  std::deque<EventRow> event_rows;
  std::vector<std::unique_ptr<dds::Subscription>> subs;
  std::map<std::string, int> series_of_topic;
  std::set<std::string> pipelines_followed;
  std::set<std::string> names_used;

  auto matches = [&](const dds::SignalMeta& m) {
    if (wanted.empty()) return true;
    for (const auto& w : wanted) {
      auto r = client->resolve(w, milliseconds(0));
      if (r && r->topic == m.topic) return true;
    }
    return false;
  };
  auto follow_new_topics = [&](milliseconds wait) -> bool {
    bool any = false;
    for (const auto& m : client->signals(wait)) {
      if (series_of_topic.count(m.topic) || !matches(m)) continue;
      record::SeriesInfo info;
      info.name = m.kind == "state" ? "state" : m.block + "." + m.port;
      if (names_used.count(info.name)) info.name = m.pipeline + "." + info.name;
      names_used.insert(info.name);
      info.topic = m.topic;
      info.kind = m.kind;
      info.names = m.names;
      info.units = m.units;
      info.rate_hz = m.rate_hz;
      info.pipeline_rate_hz = m.pipeline_rate_hz;
      info.decimation = m.decimation;
      auto id = rec.add_series(info);
      if (!id) {
        std::fprintf(stderr, "lode: %s\n", id.error().c_str());
        continue;
      }
      const int series = *id;
      auto sub = client->subscribe(m, [&, series](const dds::SignalMeta&, const dds::Sample& s) {
        std::lock_guard lock(queue_mutex);
        rows.push_back({series, s});
      });
      if (!sub) {
        std::fprintf(stderr, "lode: %s\n", sub.error().c_str());
        continue;
      }
      series_of_topic[m.topic] = series;
      subs.push_back(std::move(*sub));
      std::fprintf(stderr, "lode record: %s -> %s:/signals/%s (%g Hz)\n", m.topic.c_str(), path.c_str(),
                   info.name.c_str(), m.rate_hz);
      if (!pipelines_followed.count(m.pipeline)) {
        pipelines_followed.insert(m.pipeline);
        watch.follow(m.pipeline);
        rec.set_attribute("pipeline", m.pipeline);
        auto ev = client->subscribe_events(m.pipeline, [&](const dds::EventSample& e) {
          std::lock_guard lock(queue_mutex);
          event_rows.push_back({e});
        });
        if (ev) subs.push_back(std::move(*ev));
      }
      any = true;
    }
    return any;
  };
  bool found = follow_new_topics(wait_option(args, 10.0));
  if (found) {  // metadata arrives topic by topic: pick up the rest before the run starts
    std::this_thread::sleep_for(milliseconds(500));
    follow_new_topics(milliseconds(0));
  }
  if (!found && series_of_topic.empty()) {
    std::fprintf(stderr, "lode: nothing to record: no matching lodestone topic appeared (see `lode topics`)\n");
    return kExitFault;
  }
  auto last_scan = Clock::now();
  auto last_flush = Clock::now();
  std::string why;
  auto drain = [&] {
    std::deque<Row> r;
    std::deque<EventRow> e;
    {
      std::lock_guard lock(queue_mutex);
      r.swap(rows);
      e.swap(event_rows);
    }
    for (const auto& row : r)
      rec.append(row.series, row.sample.cycle, row.sample.stamp_ns, row.sample.captured_ns, row.sample.values.data());
    for (const auto& ev : e) {
      rec.add_event(ev.event.cycle, ev.event.stamp_ns, ev.event.kind, ev.event.text);
      if (ev.event.kind == "stop") watch.pipeline_stopped(ev.event.pipeline);
    }
  };
  while ((why = watch.reason()).empty()) {
    std::this_thread::sleep_for(milliseconds(20));
    drain();
    if (Clock::now() - last_scan > milliseconds(500)) {
      follow_new_topics(milliseconds(0));
      last_scan = Clock::now();
    }
    if (Clock::now() - last_flush > std::chrono::seconds(1)) {
      if (auto st = rec.flush(); !st) std::fprintf(stderr, "lode: %s\n", st.message().c_str());
      last_flush = Clock::now();
    }
  }
  subs.clear();
  drain();
  int rc = kExitOk;
  for (const auto& [topic, series] : series_of_topic) {
    std::fprintf(stderr, "lode record: %-44s %llu samples, %llu missing\n", topic.c_str(),
                 static_cast<unsigned long long>(rec.samples(series)), static_cast<unsigned long long>(rec.gaps(series)));
    if (rec.gaps(series) > 0) rc = kExitFault;  // never silent
  }
  if (auto st = rec.close(); !st) {
    std::fprintf(stderr, "lode: %s\n", st.message().c_str());
    return kExitFault;
  }
  std::fprintf(stderr, "lode record: wrote %s (%s)\n", path.c_str(), why.c_str());
  return rc;
}

// ---------------------------------------------------------------------------------------
namespace {

/// The pipeline a command goes to: --pipeline, "pipeline/..." in the target, or the only
/// one publishing.
std::optional<std::string> target_pipeline(const Args& args, dds::Client& client, std::string& target) {
  if (args.has("--pipeline")) return args.option("--pipeline");
  const auto slash = target.find('/');
  if (slash != std::string::npos) {
    std::string p = target.substr(0, slash);
    target = target.substr(slash + 1);
    return p;
  }
  // Discovery is gradual: the first pipeline heard of is not the only one live until no other
  // has appeared for a while. Take the set once this client has listened for 2.5 s (every
  // lodestone participant announces itself each second, so each live pipeline has had two
  // chances to be heard) and the set has held still for 2 s (a loaded host can take over a
  // second to process an announcement). A command never goes to the one that answered first.
  const auto listening_since = Clock::now();
  auto pipelines = client.pipelines(wait_option(args, 3.0));
  for (auto settled = Clock::now();
       !pipelines.empty() && (Clock::now() - settled < std::chrono::seconds(2) ||
                              Clock::now() - listening_since < std::chrono::milliseconds(2500));) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto now_live = client.pipelines(std::chrono::milliseconds(0));
    if (now_live != pipelines) {
      pipelines = std::move(now_live);
      settled = Clock::now();
    }
  }
  if (pipelines.size() == 1) return pipelines[0];
  if (pipelines.empty())
    std::fprintf(stderr, "lode: no pipeline is publishing on this domain (give --pipeline NAME, check --domain/--transport)\n");
  else {
    std::fprintf(stderr, "lode: several pipelines are live; give --pipeline NAME (or NAME/BLOCK...):");
    for (const auto& p : pipelines) std::fprintf(stderr, " %s", p.c_str());
    std::fprintf(stderr, "\n");
  }
  return std::nullopt;
}

/// The same text whichever way the reply came (local socket or DDS).
int print_reply(const ControlRequest& request, const ControlReply& reply) {
  if (!reply.value.empty() && request.kind == "list") std::printf("%s", reply.value.c_str());
  std::printf("%s: %s\n", reply.ok ? "ok" : "error", reply.message.c_str());
  return reply.ok ? kExitOk : kExitFault;
}

std::optional<milliseconds> timeout_option(const Args& args) {
  const auto timeout = number_option(args, "--timeout", 5.0, 0.01, 600);
  if (!timeout) return std::nullopt;
  return milliseconds(static_cast<long long>(*timeout * 1e3));
}

std::uint64_t new_request_id() { return static_cast<std::uint64_t>(Clock::now().time_since_epoch().count()); }

int send(const Args& args, dds::Client& client, const std::string& pipeline, ControlRequest request) {
  const auto timeout = timeout_option(args);
  if (!timeout) return kExitConfig;
  request.id = new_request_id();
  auto reply = client.command(pipeline, request, *timeout);
  if (!reply) {
    std::fprintf(stderr, "lode: %s\n", reply.error().c_str());
    return kExitFault;
  }
  return print_reply(request, *reply);
}

/// A command to a pipeline, over its local socket when there is one, else over DDS.
///   --local: the socket or nothing; --dds: DDS only (as before the local socket existed).
///   Which pipeline: --pipeline NAME, the "NAME/" prefix of the target (stripped here), or,
///   with neither, the one pipeline with a live local socket (several: say which ones).
/// `make` builds the request from the target without its prefix; nullopt = usage error
/// (already printed).
int dispatch(const Args& args, const std::string& role, std::string target,
             const std::function<std::optional<ControlRequest>(const std::string&)>& make) {
  const bool force_local = args.has_flag("--local");
  const bool force_dds = args.has_flag("--dds");
  if (force_local && force_dds) {
    std::fprintf(stderr, "lode: --local and --dds exclude each other\n");
    return kExitConfig;
  }
  std::optional<std::string> pipeline;
  if (args.has("--pipeline")) {
    pipeline = args.option("--pipeline");
  } else if (const auto slash = target.find('/'); slash != std::string::npos) {
    pipeline = target.substr(0, slash);
    target = target.substr(slash + 1);
  }
  if (pipeline && pipeline->empty()) {
    std::fprintf(stderr, "lode: empty pipeline name\n");
    return kExitConfig;
  }
  auto request = make(target);
  if (!request) return kExitConfig;

  std::optional<std::string> socket;  // set: go local
  if (!force_dds) {
    if (pipeline) {
      const std::string path = local_control_socket(*pipeline);
      // --local: even a dead or missing socket, so the error says what is wrong with it.
      if (force_local || probe_local_socket(path)) socket = path;
    } else {
      const auto live = live_local_pipelines();
      if (live.size() == 1) {
        socket = live[0].path;
      } else if (live.size() > 1) {
        std::fprintf(stderr, "lode: several pipelines run on this host; give --pipeline NAME (or NAME/...), or --dds for a remote one:");
        for (const auto& p : live) std::fprintf(stderr, " %s (pid %d)", p.pipeline.c_str(), static_cast<int>(p.pid));
        std::fprintf(stderr, "\n");
        return kExitConfig;  // refuse to guess
      } else if (force_local) {
        std::fprintf(stderr, "lode: no pipeline runs on this host with a local command socket (looked in %s)\n",
                     local_control_dir().c_str());
        return kExitFault;
      }
    }
  }
  if (socket) {
    const auto timeout = timeout_option(args);
    if (!timeout) return kExitConfig;
    request->id = new_request_id();
    if (request->kind == "record_start" && !request->name.empty() && request->name[0] != '/') {
      // Same host: a relative file means relative to the caller, not to the runner's cwd.
      char cwd[4096];
      if (getcwd(cwd, sizeof cwd)) request->name = std::string(cwd) + "/" + request->name;
    }
    char host[256] = "host";
    gethostname(host, sizeof host - 1);
    request->client = "lode-" + role + "-" + std::to_string(getpid()) + "@" + host;
    auto reply = local_send(*socket, *request, *timeout);
    if (!reply) {
      std::fprintf(stderr, "lode: %s\n", reply.error().c_str());
      return kExitFault;
    }
    return print_reply(*request, *reply);
  }
  auto client = make_client(args, role);
  if (!client) return kExitConfig;
  if (!pipeline) pipeline = target_pipeline(args, *client, target);
  // None live, or several and none named: a command must never go to a guessed pipeline.
  if (!pipeline) return kExitConfig;
  return send(args, *client, *pipeline, *request);
}

}  // namespace

int cmd_set(const Args& args) {
  const bool list = args.has_flag("--list");
  if ((!list && (args.positional.empty() || args.positional.size() > 2)) || (list && args.positional.size() > 1)) {
    std::fprintf(stderr, "usage: lode set [PIPELINE/]BLOCK.PARAM VALUE   (set)\n"
                         "       lode set [PIPELINE/]BLOCK.PARAM         (read the value in force)\n"
                         "       lode set --list [[PIPELINE/]BLOCK]      (runtime parameters and ranges)\n"
                         "       [--pipeline NAME] [--local | --dds] [--timeout S]\n");
    return kExitConfig;
  }
  const std::string target = args.positional.empty() ? "" : args.positional[0];
  return dispatch(args, "set", target, [&](const std::string& t) -> std::optional<ControlRequest> {
    ControlRequest r;
    if (list) {
      r.kind = "list";
      r.block = t;
      return r;
    }
    const auto dot = t.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == t.size()) {
      std::fprintf(stderr, "lode: expected BLOCK.PARAM, got '%s'\n", t.c_str());
      return std::nullopt;
    }
    r.block = t.substr(0, dot);
    r.name = t.substr(dot + 1);
    r.kind = args.positional.size() == 2 ? "set" : "get";
    if (args.positional.size() == 2) r.value = args.positional[1];
    return r;
  });
}

/// Ask the running pipeline to record every output on its own host (record_start/stop).
int remote_record(const Args& args) {
  return dispatch(args, "record", "", [&](const std::string&) -> std::optional<ControlRequest> {
    ControlRequest r;
    r.kind = args.has("--remote-start") ? "record_start" : "record_stop";
    r.name = args.option("--remote-start");
    return r;
  });
}

int cmd_swap(const Args& args) {
  const bool promote = args.has("--promote");
  if ((!promote && args.positional.size() != 2) || (promote && !args.positional.empty() && args.positional.size() != 1)) {
    std::fprintf(stderr, "usage: lode swap [PIPELINE/]BLOCK PLUGIN [--params '{key: value, ...}'] [--shadow-cycles N] [--cold]\n"
                         "       lode swap --promote [PIPELINE/]SHADOW\n"
                         "       [--pipeline NAME] [--local | --dds] [--timeout S]\n");
    return kExitConfig;
  }
  const std::string target = promote ? args.option("--promote") : args.positional[0];
  // Swap options travel in the request's name field: "shadow_cycles=N;warm_start=false".
  std::string swap_options;
  if (args.has("--shadow-cycles")) {
    const auto n = number_option(args, "--shadow-cycles", 0, 0, 1e7);
    if (!n) return kExitConfig;
    swap_options = "shadow_cycles=" + std::to_string(static_cast<long long>(*n));
  }
  if (args.has_flag("--cold")) swap_options += std::string(swap_options.empty() ? "" : ";") + "warm_start=false";
  return dispatch(args, "swap", target, [&](const std::string& t) -> std::optional<ControlRequest> {
    ControlRequest r;
    r.kind = "swap";
    if (promote) {
      r.name = t;  // the shadow to promote
      r.block = args.positional.empty() ? "" : args.positional[0];
      r.plugin = "";
      r.value = "promote";
    } else {
      r.block = t;
      r.plugin = args.positional[1];
      r.value = args.option("--params");
      r.name = swap_options;
    }
    return r;
  });
}

}  // namespace lode::cli
