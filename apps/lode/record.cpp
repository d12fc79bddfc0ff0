// lode record FILE: every live topic (or --topics) and the events into one HDF5 file until
// Ctrl-C, --duration, or the pipelines stop; a lost sample is counted per series and makes
// the exit code 1, while the periods a real-time loop skipped after overruns (which publish
// nothing) are told apart by the pipelines' timing reports (sample_continuity.hpp). With
// --remote-start/--remote-stop: ask the running pipeline to record every output on its own
// host instead.
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "commands.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "remote_client.hpp"
#include "sample_continuity.hpp"

namespace lode::cli {
namespace {

using Clock = std::chrono::steady_clock;

int record_topics(const Args& args) {
  if (args.positional.size() != 1) {
    std::fprintf(stderr, "lode record: give the FILE to write (or --remote-start FILE / --remote-stop)\n"
                         "see: lode record --help\n");
    return kExitConfig;
  }
  const double duration = args.number("--duration", 0.0);
  const std::string path = args.positional[0];
  const auto wanted = split_list(args.option("--topics"));
  // The file first: a path that cannot be written is refused before anything starts.
  auto recorder = record::Recorder::create(path, "lode record");
  if (!recorder) {
    std::fprintf(stderr, "lode record: %s\n", recorder.error().c_str());
    return kExitConfig;
  }
  auto& rec = **recorder;
  // A recording that got nothing is not left behind: it is only something to trip over.
  const auto discard_file = [&] {
    (void)rec.close();
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  };
  auto client = make_client(args, "record");
  if (!client) {
    discard_file();
    return kExitConfig;
  }
  install_stop_handlers();
  StopWatch watch(duration);

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
  std::deque<dds::TimingSample> timing_rows;
  std::vector<std::unique_ptr<dds::Subscription>> subs;
  // Kept until the end: the last timing report places the last gaps.
  std::vector<std::unique_ptr<dds::Subscription>> timing_subs;
  std::map<std::string, int> series_of_topic;
  struct Continuity {
    std::string pipeline;
    SampleContinuity samples;
  };
  std::map<int, Continuity> continuity;  // by series
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
      continuity.emplace(series, Continuity{m.pipeline, SampleContinuity(m.decimation)});
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
        auto timing = client->subscribe_timing(m.pipeline, [&](const dds::TimingSample& t) {
          std::lock_guard lock(queue_mutex);
          timing_rows.push_back(t);
        });
        if (timing) timing_subs.push_back(std::move(*timing));
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
    std::fprintf(stderr, "lode: nothing to record: no matching lodestone topic appeared (see `lode topics`); "
                         "%s not written\n", path.c_str());
    discard_file();
    return kExitFault;
  }
  auto last_scan = Clock::now();
  auto last_flush = Clock::now();
  std::string why;
  auto drain = [&] {
    std::deque<Row> r;
    std::deque<EventRow> e;
    std::deque<dds::TimingSample> t;
    {
      std::lock_guard lock(queue_mutex);
      r.swap(rows);
      e.swap(event_rows);
      t.swap(timing_rows);
    }
    for (const auto& row : r) {
      rec.append(row.series, row.sample.cycle, row.sample.stamp_ns, row.sample.captured_ns, row.sample.values.data());
      if (auto it = continuity.find(row.series); it != continuity.end())
        it->second.samples.add(row.sample.writer, row.sample.sequence, row.sample.cycle);
    }
    for (const auto& timing : t)
      for (auto& [series, c] : continuity)
        if (c.pipeline == timing.pipeline) c.samples.timing(timing.cycle, timing.telemetry_dropped);
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
  // A gap after the last timing report is placed by the next one (a running pipeline reports
  // at telemetry.timing_rate_hz, 2 Hz by default): wait for it, not for a stopped pipeline.
  const auto placed = [&] {
    for (const auto& [series, c] : continuity)
      if (c.samples.unsent() > 0 && !c.samples.timing_reaches(c.samples.last_cycle()) &&
          !watch.stopped(c.pipeline))
        return false;
    return true;
  };
  for (const auto give_up = Clock::now() + std::chrono::seconds(3); !placed() && Clock::now() < give_up;) {
    std::this_thread::sleep_for(milliseconds(50));
    drain();
  }
  timing_subs.clear();
  drain();
  int rc = kExitOk;
  for (const auto& [topic, series] : series_of_topic) {
    const SampleContinuity& c = continuity.at(series).samples;
    const SampleContinuity::Verdict verdict = c.classify();
    rec.account(series, verdict.missing, verdict.skipped);
    std::string skipped;
    if (verdict.skipped > 0)
      skipped = ", " + std::to_string(verdict.skipped) + " not due (periods the loop skipped after overruns)";
    std::fprintf(stderr, "lode record: %-44s %llu samples, %llu missing%s\n", topic.c_str(),
                 static_cast<unsigned long long>(rec.samples(series)),
                 static_cast<unsigned long long>(verdict.missing), skipped.c_str());
    if (verdict.missing > 0) rc = kExitFault;  // never silent
  }
  if (auto st = rec.close(); !st) {
    std::fprintf(stderr, "lode: %s\n", st.message().c_str());
    return kExitFault;
  }
  std::fprintf(stderr, "lode record: wrote %s (%s)\n", path.c_str(), why.c_str());
  report_malformed(*client, "record");
  for (const auto& pipeline : pipelines_followed) warn_namesakes(*client, pipeline, "record");
  return rc;
}

/// Ask the running pipeline to record every output on its own host (record_start/stop).
int record_remotely(const Args& args) {
  return send_command(args, "record", "", [&](const std::string&) -> std::optional<ControlRequest> {
    ControlRequest r;
    r.kind = args.has("--remote-start") ? "record_start" : "record_stop";
    r.name = args.option("--remote-start");
    return r;
  });
}

int record(const Args& args) {
  if (args.has("--remote-start") || args.has_flag("--remote-stop")) return record_remotely(args);
  return record_topics(args);
}

}  // namespace

Command record_command() {
  return {"record",
          "record live topics and events to HDF5 (stops on Ctrl-C, --duration, or when the pipelines stop); or ask a "
          "running pipeline to record on its own host",
          [](Declare& d) {
            d.positional("FILE", "the HDF5 file to write", 0, 1);
            d.text("--topics", "A,B", "only these topics");
            d.number("--duration", "S", "stop after S seconds", 0, 1e9);
            d.text("--remote-start", "FILE", "ask the running pipeline to record every output into FILE on its host");
            d.flag("--remote-stop", "ask the running pipeline to stop recording");
            d.flag("--quiet", "no progress");
            d.command_route_options();
            d.dds_options();
          },
          record};
}

}  // namespace lode::cli
