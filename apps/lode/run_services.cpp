#include "run_services.hpp"

#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "cli.hpp"
#include "local_control.hpp"
#include "lode/control.hpp"
#include "lode/hot_swap.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/dds/bridge.hpp"
#include "run_recording.hpp"
#include "lode/sdk/rt_log.hpp"
#include "lode/telemetry.hpp"

namespace lode::cli {

namespace {

std::string hostname() {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  return host;
}

}  // namespace

struct RunServices::Impl {
  Pipeline* pipeline = nullptr;
  Scheduler* scheduler = nullptr;
  EventLog* events = nullptr;
  const RunStats* stats = nullptr;
  RunServiceOptions options;
  TelemetrySpec spec;
  std::unique_ptr<OutputDigest> digest;
  std::unique_ptr<TelemetryTap> telemetry_tap;
  std::unique_ptr<HotSwap> hot_swap;
  std::unique_ptr<ControlService> control;
  std::unique_ptr<LocalControlServer> local_server;
  LocalControlStats local_stats;  // kept after the server stops, for the summary
  std::string local_socket;
  std::unique_ptr<dds::TelemetryBridge> bridge;

  std::unique_ptr<RunRecorder> recorder;
  std::uint64_t sim_waits = 0;
  std::uint64_t last_published = 0;
  std::chrono::steady_clock::time_point last_progress = std::chrono::steady_clock::now();
  bool stall_reported = false;
};

RunServices::RunServices() : impl_(std::make_unique<Impl>()) {}

RunServices::~RunServices() {
  if (impl_) finish();
}

Expected<std::unique_ptr<RunServices>> RunServices::start(Pipeline& pipeline, Scheduler& scheduler,
                                                          EventLog& events, const RunServiceOptions& options) {
  std::unique_ptr<RunServices> s(new RunServices());
  Impl& im = *s->impl_;
  im.pipeline = &pipeline;
  im.scheduler = &scheduler;
  im.events = &events;
  im.stats = &scheduler.stats();
  im.options = options;
  im.spec = pipeline.telemetry();
  if (options.domain) im.spec.domain = *options.domain;
  const bool telemetry = im.spec.enabled && options.telemetry;
  // A simulated run (lode run --clock sim, lode replay) times the ops of one cycle in 64:
  // timing every op of every cycle was a fifth of kawato_planar's simulated cycle, and the
  // per-block statistics it reports (summary, timing topic, replay's median step) need the
  // distribution, not every sample. A real-clock run times every cycle: its worst case matters.
  if (options.simulated) scheduler.set_simulated_timing_stride(kSimulatedTimingStride);

  // Order on the RT thread: swaps and commands before the cycle; taps and digest after it.
  // The command service always exists: the local socket reaches it without Fast DDS, the
  // DDS bridge only when the YAML enables telemetry commands.
  im.hot_swap = std::make_unique<HotSwap>(pipeline, events);
  scheduler.add_hook(im.hot_swap.get());
  im.control = std::make_unique<ControlService>(pipeline, events);
  scheduler.add_hook(im.control.get());
  im.control->set_swap_handler([hs = im.hot_swap.get()](const ControlRequest& r, std::unique_lock<std::mutex>& commands) {
    return hs->handle(r, &commands);
  });
  im.digest = std::make_unique<OutputDigest>(pipeline.signals(), options.digest);
  scheduler.add_hook(im.digest.get());
  im.recorder = std::make_unique<RunRecorder>(pipeline, scheduler, events, *im.digest);
  scheduler.add_hook(&im.recorder->hook());
  im.control->set_record_handler([&im](const ControlRequest& r) { return im.recorder->handle(r); });
  if (!options.record_path.empty()) {
    im.recorder->set_source(options.record_source);
    if (auto st = im.recorder->open(options.record_path, options.record_rows); !st) return st;
  }
  if (options.local_control) {
    auto server = LocalControlServer::start(*im.control, pipeline.name());
    if (!server) return Status::error("local control: " + server.error());
    im.local_server = std::move(*server);
    im.local_socket = im.local_server->path();
    if (im.local_server->replaced_stale())
      events.post(0, 0, "warning", "local control: replaced a stale socket left by a run that ended abnormally: " +
                                       im.local_socket);
  }
  if (telemetry) {
    // On the simulated clock nothing is late: the publisher keeps normal scheduling.
    if (options.simulated) im.spec.publisher_priority = 0;
    im.telemetry_tap = std::make_unique<TelemetryTap>(im.spec, pipeline.rate_hz());
    scheduler.add_hook(im.telemetry_tap.get());
    dds::ParticipantOptions po;
    po.domain = im.spec.domain;
    po.name = dds::pipeline_participant_name(pipeline.name(), hostname());
    po.transport = im.spec.transport;
    po.security = im.spec.security;
    auto bridge = dds::TelemetryBridge::start(pipeline, im.spec, *im.telemetry_tap, scheduler.stats(), events,
                                              im.spec.commands.enabled ? im.control.get() : nullptr, po);
    if (!bridge) return Status::error("telemetry: " + bridge.error());
    im.bridge = std::move(*bridge);
  }
  return s;
}

bool RunServices::wait_for_subscribers() {
  Impl& im = *impl_;
  if (im.options.wait_subscribers <= 0) return true;
  if (!im.bridge) return false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(im.options.wait_s);
  while (im.bridge->matched_readers() < static_cast<std::size_t>(im.options.wait_subscribers)) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

void RunServices::set_running(bool running) {
  impl_->recorder->set_running(running);
  // On the simulated clock on_idle() runs between the cycles, on their thread: a replay's
  // recording gets a thread of its own while they run (with the real clock on_idle() already
  // runs beside the RT thread). Only a replay (its length known, the file laid out for it):
  // `lode run --clock sim` keeps writing between its cycles, where the moments it writes and
  // flushes at, and so what a full disk leaves in its file (the fault matrix), are those of
  // its cycle count, not of a second thread's timing.
  if (impl_->options.simulated && impl_->options.record_rows > 0) {
    if (running) impl_->recorder->start_writer();
    else impl_->recorder->stop_writer();
  }
  impl_->hot_swap->set_running(running);
  impl_->control->set_running(running);
}

void RunServices::on_idle() {
  Impl& im = *impl_;
  im.hot_swap->poll_events();  // health-monitor trips and fallbacks become events (recorded, published)
  im.recorder->on_idle();
  if (im.telemetry_tap && im.bridge) {
    // Watchdog: samples waiting but nothing published for 3 s means the publisher thread
    // is stuck (inside Fast DDS); say so once. The RT side keeps running and counts drops.
    const auto published = im.bridge->stats().published;
    const auto now = std::chrono::steady_clock::now();
    std::size_t waiting = 0;
    for (const auto& c : im.telemetry_tap->channels()) waiting += c.ring->size();
    if (published != im.last_published || waiting == 0) {
      im.last_published = published;
      im.last_progress = now;
    } else if (!im.stall_reported && now - im.last_progress > std::chrono::seconds(3)) {
      im.stall_reported = true;
      im.events->post(im.stats->last_time_ns.load(), im.stats->cycles.load(), "warning",
                      "telemetry: publisher made no progress for 3 s with " + std::to_string(waiting) +
                          " samples waiting (stuck inside Fast DDS?); the loop is unaffected, samples are dropped and counted");
    }
  }
  if (!im.options.simulated || !im.telemetry_tap || !im.bridge || im.stall_reported) return;
  // Simulated clock: hold the simulation (there is no deadline) until every ring has room
  // for the next batch of cycles; give up after 5 s of no progress (then drops are counted).
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  for (;;) {
    bool room = true;
    for (const auto& c : im.telemetry_tap->channels()) room = room && c.ring->size() * 2 <= c.ring->capacity();
    if (room || std::chrono::steady_clock::now() > give_up) break;
    ++im.sim_waits;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

void RunServices::finish() {
  Impl& im = *impl_;
  if (im.local_server) {
    im.local_server->stop();  // no command arrives after the stop event
    im.local_stats = im.local_server->stats();
    im.local_server.reset();
  }
  if (im.hot_swap) im.hot_swap->poll_events();
  if (im.recorder) {
    if (auto st = im.recorder->close(); !st) std::fprintf(stderr, "lode: recording: %s\n", st.message().c_str());
  }
  if (im.bridge) {
    // Publish the rest and close the participant, but never wait for ever: Fast DDS 2.9.1
    // has lock-order bugs in its reliable writer (we have seen the publisher thread
    // deadlock inside DataWriter::write while readers joined and left). The loop never
    // depends on it; the run must not hang on it either.
    auto done = std::make_shared<std::atomic<bool>>(false);
    dds::TelemetryBridge* bridge = im.bridge.get();
    std::thread stopper([bridge, done] {
      bridge->flush();
      bridge->stop();
      done->store(true);
    });
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!done->load() && std::chrono::steady_clock::now() < give_up)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    last_bridge_stats_ = im.bridge->stats();
    if (done->load()) {
      stopper.join();
      im.bridge.reset();  // finish() is idempotent: the destructor calls it again
    } else {
      stopper.detach();
      (void)im.bridge.release();  // stuck inside Fast DDS: deleting it would hang too
      dds_stuck_ = true;
      im.events->post(im.stats->last_time_ns.load(), im.stats->cycles.load(), "warning",
                      "telemetry: the DDS publisher did not stop within 10 s (stuck inside Fast DDS); "
                      "exiting without a clean DDS shutdown");
    }
  }
}

std::string RunServices::output_digest() const { return impl_->digest->text(); }

DigestAlgorithm RunServices::output_digest_algorithm() const { return impl_->digest->algorithm(); }

const std::vector<std::string>& RunServices::io_blocks() const { return impl_->recorder->io_blocks(); }

Expected<RunResult> execute_run(Pipeline& pipeline, Scheduler& scheduler, EventLog& events, RunServices& services,
                                std::uint64_t cycles, const std::string& start_text,
                                const std::function<void()>& on_idle, const std::function<void()>& after_run,
                                const std::function<void()>& on_active) {
  if (auto st = pipeline.activate(); !st) return st;
  events.post(0, 0, "start", start_text);
  if (on_active) on_active();
  services.set_running(true);
  auto result = scheduler.run(cycles, stop_requested(), on_idle);
  services.set_running(false);
  pipeline.deactivate();  // drives every output safe
  if (after_run) after_run();
  const auto& st = scheduler.stats();
  events.post(st.last_time_ns.load(), st.cycles.load(), "stop",
              result.faulted ? "fault: " + result.fault
                             : result.stopped_by_request ? "stopped by signal" : "completed");
  services.finish();  // publishes the stop event and the last samples, closes the recording
  return result;
}

std::string keep_threads_off_cpu(int rt_cpu) {
  if (rt_cpu < 0 || rt_cpu >= CPU_SETSIZE) return "";
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (const int rc = pthread_getaffinity_np(pthread_self(), sizeof allowed, &allowed); rc != 0)
    return std::string("cannot read the CPU affinity (") + std::strerror(rc) + "); lode's other threads may share cpu " +
           std::to_string(rt_cpu) + " with the RT thread";
  if (!CPU_ISSET(rt_cpu, &allowed)) return "";  // already elsewhere (isolcpus, CPUAffinity=)
  CPU_CLR(rt_cpu, &allowed);
  if (CPU_COUNT(&allowed) == 0) return "";  // the RT CPU is the only one allowed: nowhere to go
  if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof allowed, &allowed); rc != 0)
    return std::string("cannot keep lode's other threads off cpu ") + std::to_string(rt_cpu) + " (" + std::strerror(rc) +
           "); they may share it with the RT thread";
  return "";
}

Json RunServices::summary() const {
  const Impl& im = *impl_;
  Json j = Json::object();
  j["output_digest"] = output_digest();
  j[kDigestAlgorithmKey] = digest_algorithm_name(output_digest_algorithm());
  if (im.telemetry_tap) {
    Json t = Json::object();
    t["domain"] = static_cast<std::int64_t>(im.spec.domain);
    t["transport"] = to_string(im.spec.transport.kind);
    t["samples_offered"] = im.telemetry_tap->offered();
    t["ring_dropped"] = im.telemetry_tap->dropped();
    // What waking the publisher cost the RT thread: rings, the ones that had to make a system
    // call, and the time those calls took.
    const PublishDoorbell& doorbell = im.telemetry_tap->doorbell();
    t["doorbell_rings"] = static_cast<std::uint64_t>(doorbell.sequence());
    t["doorbell_wakes"] = doorbell.wakes();
    t["doorbell_wake_ns"] = doorbell.wake_ns();
    t["simulation_held"] = im.sim_waits;
    {
      const auto b = im.bridge ? im.bridge->stats() : last_bridge_stats_;
      t["published"] = b.published;
      t["commands_accepted"] = b.commands_accepted;
      t["commands_refused"] = b.commands_refused;
      t["commands_malformed"] = b.commands_malformed;
      t["publisher_priority_asked"] = static_cast<std::int64_t>(im.spec.publisher_priority);
      t["publisher_priority"] = static_cast<std::int64_t>(b.publisher_priority);
      t["publisher_stalled"] = im.stall_reported;
      t["clean_shutdown"] = !dds_stuck_;
    }
    j["telemetry"] = std::move(t);
  }
  j["recordings"] = im.recorder ? im.recorder->finished() : Json::array();
  if (!im.local_socket.empty()) {
    const LocalControlStats ls = im.local_server ? im.local_server->stats() : im.local_stats;
    Json l = Json::object();
    l["socket"] = im.local_socket;
    l["connections"] = ls.connections;
    l["requests"] = ls.requests;
    l["malformed"] = ls.malformed;
    l["refused_clients"] = ls.refused_clients;
    l["idle_closed"] = ls.idle_closed;
    j["local_control"] = std::move(l);
  }
  if (im.hot_swap) {
    Json h = Json::object();
    h["swaps"] = im.hot_swap->swaps();
    const auto& c = im.hot_swap->rt_cost();
    if (c.count() > 0) {
      h["rt_cost_p50_ns"] = static_cast<double>(c.percentile(0.5));
      h["rt_cost_max_ns"] = static_cast<double>(c.max());
    }
    // Did a swap cause an overrun? The exchange runs in before_cycle of its cycle and the
    // jump snapshot in after_cycle, so an overrun it caused is in that cycle (or, through a
    // late start, the next). Overruns are attributed from the scheduler's overrun log.
    if (im.stats && im.stats->overruns.load() > 0) {
      const auto overrun_cycles = im.stats->logged_overruns();
      const auto& swap_cycles = im.hot_swap->swap_cycles();
      std::uint64_t at_swaps = 0;
      for (std::uint64_t o : overrun_cycles)
        for (std::uint64_t swap_cycle : swap_cycles)
          if (o == swap_cycle || o == swap_cycle + 1) {
            ++at_swaps;
            break;
          }
      h["overruns_at_swap_cycles"] = at_swaps;
      h["overruns_attributed"] = static_cast<std::uint64_t>(overrun_cycles.size());
    } else {
      h["overruns_at_swap_cycles"] = std::uint64_t{0};
    }
    j["hot_swap"] = std::move(h);
  }
  return j;
}

}  // namespace lode::cli
