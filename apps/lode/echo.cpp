// lode echo TOPIC: live samples of one topic (a block's output, the state, events or timing)
// as text, one line per sample, or a table updated in place; counts the samples a reader
// missed (by cycle number) and, with --latency, the delay from capture on the RT thread.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <thread>

#include "commands.hpp"
#include "lode/sdk/histogram.hpp"
#include "remote_client.hpp"
#include "sample_continuity.hpp"

namespace lode::cli {
namespace {

using Clock = std::chrono::steady_clock;

int echo(const Args& args) {
  // 0: no limit.
  const auto count = static_cast<std::uint64_t>(args.integer("--count", 0));
  const double duration = args.number("--duration", 0.0);
  auto client = make_client(args, "echo");
  if (!client) return kExitConfig;
  install_stop_handlers();
  StopWatch watch(duration);
  const std::string what = args.positional[0];
  const bool table = args.has_flag("--table") && isatty(STDOUT_FILENO);
  std::mutex out_mutex;
  std::uint64_t received = 0;
  std::optional<SampleContinuity> continuity;  // of the signal echoed
  std::optional<std::uint64_t> first_cycle, last_cycle;
  std::vector<std::unique_ptr<dds::Subscription>> subs;
  // --latency: capture on the RT thread -> taken by this process (same host: one clock).
  const bool latency = args.has_flag("--latency");
  const bool quiet = args.has_flag("--quiet");
  // Exact quantiles from the first kExactLatencies samples (8 MB); past them, a fixed-size
  // histogram (within 3 %) that has seen every sample, so an overnight echo stays bounded.
  constexpr std::size_t kExactLatencies = 1 << 20;
  std::vector<double> latencies_us;
  lode::Histogram latency_histogram;
  if (latency) latencies_us.reserve(kExactLatencies);
  std::string followed;  // the pipeline of the topic echoed
  bool warned_namesakes = false;

  if (what == "events" || what == "timing" || what.ends_with("/events") || what.ends_with("/timing")) {
    const bool events = what.ends_with("events");
    std::string pipeline = what.find('/') != std::string::npos ? what.substr(0, what.rfind('/')) : args.option("--pipeline");
    if (pipeline.rfind("lode/", 0) == 0) pipeline = pipeline.substr(5);
    Expected<std::unique_ptr<dds::Subscription>> sub = Status::error("unreachable");
    // A pipeline's events end with its "stop" event: once every pipeline heard from (or the
    // one named) has stopped, echo is done too.
    if (events && !pipeline.empty()) watch.follow(pipeline);
    if (events) {
      sub = client->subscribe_events(pipeline, [&](const dds::EventSample& e) {
        std::lock_guard lock(out_mutex);
        if (count > 0 && received >= count) return;
        if (!quiet) {
          std::printf("%-16s cycle %-10llu t %.6f s  [%s] %s\n", e.pipeline.c_str(),
                      static_cast<unsigned long long>(e.cycle), static_cast<double>(e.stamp_ns) * 1e-9,
                      e.kind.c_str(), e.text.c_str());
          std::fflush(stdout);
          if (std::ferror(stdout)) watch.output_closed();
        }
        watch.follow(e.pipeline);
        if (e.kind == "stop") watch.pipeline_stopped(e.pipeline);
        if (++received == count) watch.done();
      });
    } else {
      sub = client->subscribe_timing(pipeline, [&](const dds::TimingSample& t) {
        std::lock_guard lock(out_mutex);
        if (count > 0 && received >= count) return;
        if (++received == count) watch.done();
        if (quiet) return;
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
        if (std::ferror(stdout)) watch.output_closed();
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
    followed = m.pipeline;
    warned_namesakes = warn_namesakes(*client, m.pipeline, "echo");
    std::string header = "# " + m.topic + "  " + std::to_string(m.rate_hz) + " Hz\n# cycle t[s]";
    for (std::size_t k = 0; k < m.names.size(); ++k)
      header += " " + m.names[k] + unit_suffix(k < m.units.size() ? m.units[k] : "");
    if (!quiet) {
      std::printf("%s\n", header.c_str());
      std::fflush(stdout);
    }
    auto last_table = Clock::now();
    auto sub = client->subscribe(m, [&](const dds::SignalMeta& meta_, const dds::Sample& s) {
      std::lock_guard lock(out_mutex);
      if (count > 0 && received >= count) return;  // enough; the rest arrives while unsubscribing
      // Missing: by each writer's sample numbers (a namesake pipeline on another cycle count
      // is another writer); the cycles shown: the first and the newest.
      if (!continuity) continuity.emplace(meta_.decimation);
      continuity->add(s.writer, s.sequence, s.cycle);
      if (!first_cycle) first_cycle = s.cycle;
      if (!last_cycle || s.cycle > *last_cycle) last_cycle = s.cycle;
      ++received;
      if (latency) {
        const std::int64_t delay_ns = s.received_ns - s.captured_ns;
        latency_histogram.record(std::max<std::int64_t>(delay_ns, 0));
        if (latencies_us.size() < kExactLatencies) latencies_us.push_back(static_cast<double>(delay_ns) * 1e-3);
      }
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
      // A write to a reader that has gone fails (EPIPE, ignored as a signal): stop cleanly.
      if (std::ferror(stdout)) watch.output_closed();
      if (count > 0 && received >= count) watch.done();
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
  if (first_cycle) {
    // Echo follows no timing reports: a cycle never published is said as such, not as lost.
    std::string unsent;
    if (continuity->writers() > 1)
      unsent += ", from " + std::to_string(continuity->writers()) + " publishers (a pipeline restarted, or namesakes)";
    if (continuity->unsent() > 0)
      unsent += ", " + std::to_string(continuity->unsent()) +
               " never published (periods the loop skipped after overruns, or telemetry_dropped in `lode echo timing`)";
    std::fprintf(stderr, "lode echo: %llu samples, cycles %llu..%llu, %llu missing%s, %llu out of order (%s)\n",
                 static_cast<unsigned long long>(received), static_cast<unsigned long long>(*first_cycle),
                 static_cast<unsigned long long>(*last_cycle), static_cast<unsigned long long>(continuity->lost()),
                 unsent.c_str(), static_cast<unsigned long long>(continuity->out_of_order()), why.c_str());
  } else
    std::fprintf(stderr, "lode echo: %llu samples (%s)\n", static_cast<unsigned long long>(received), why.c_str());
  report_malformed(*client, "echo");
  if (!warned_namesakes && !followed.empty()) warn_namesakes(*client, followed, "echo");
  if (latency && latency_histogram.count() > latencies_us.size()) {
    const auto q = [&](double p) { return static_cast<double>(latency_histogram.percentile(p)) * 1e-3; };
    std::fprintf(stderr, "lode echo: latency RT capture -> received (us): p50 %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f  "
                         "(%llu samples, more than %zu: quantiles from a histogram, within 3 %%)\n",
                 q(0.5), q(0.9), q(0.99), q(0.999), static_cast<double>(latency_histogram.max()) * 1e-3,
                 static_cast<unsigned long long>(latency_histogram.count()), kExactLatencies);
  } else if (latency && !latencies_us.empty()) {
    std::sort(latencies_us.begin(), latencies_us.end());
    auto q = [&](double p) { return latencies_us[static_cast<std::size_t>(p * static_cast<double>(latencies_us.size() - 1))]; };
    std::fprintf(stderr, "lode echo: latency RT capture -> received (us): p50 %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f  (%zu samples)\n",
                 q(0.5), q(0.9), q(0.99), q(0.999), latencies_us.back(), latencies_us.size());
  }
  if (why == "output closed") return kExitOk;  // the reader had what it wanted (`| head -3`)
  if (count > 0 && received < count) return kExitFault;
  return received > 0 ? kExitOk : kExitFault;
}

}  // namespace

Command echo_command() {
  return {"echo", "live samples: one line per sample (cycle, time, values) or a table",
          [](Declare& d) {
            d.positional("TOPIC", "a topic, BLOCK.PORT, state, events or timing", 1, 1);
            d.integer("--count", "N", "stop after N samples", 1, 1000000000000LL);
            d.number("--duration", "S", "stop after S seconds", 0, 1e9);
            d.flag("--table", "a table that updates in place");
            d.flag("--latency", "print the delivery latency of each sample");
            d.flag("--quiet", "print no samples (nor the header): only the summary on stderr, with --latency its statistics");
            d.text("--pipeline", "NAME", "the pipeline whose topic (or events, timing) to show when several run");
            d.number("--wait", "S", "how long to wait for the topic (default 5)", 0, 3600);
            d.dds_options();
          },
          echo,
          // Topic names need seconds of DDS discovery (lode topics): only the fixed ones.
          "echo events timing state"};
}

}  // namespace lode::cli
