// The telemetry bridge: two non-RT threads and the DDS entities of one pipeline.
//
// "lode-telemetry" drains the TelemetryTap's rings when the RT thread rings its doorbell
// (at the latest every publish_period_ms) and writes the samples, the timing statistics
// (every 1/timing_rate_hz) and new events. "lode-commands"
// takes commands in arrival order, checks who sent them against telemetry.commands and
// hands the allowed ones to the ControlService, which waits for the RT thread to apply
// them; the Fast DDS listener threads only wake it up, so a slow command never holds
// discovery or data delivery.
//
// Who may command: the sender of a command is the participant whose GUID prefix is in the
// sample's writer GUID; discovery (on_participant_discovery) told us its name and the IPv4
// addresses of its unicast locators. `allow_participants` is checked against that name,
// `allow_hosts` against those addresses; a peer that also has shared-memory locators is on
// this host and additionally matches "127.0.0.1" (an SHM-only peer has no address at all).
// Neither name nor address is authenticated without DDS Security (telemetry.security).
//
// A subscriber in the same process is served by Fast DDS's intra-process delivery: its
// callback runs on "lode-telemetry" inside write(). A slow in-process callback therefore
// stalls publishing (the rings fill and count drops; the RT thread is never affected).
#include "bridge_impl.hpp"
#include "lode/realtime.hpp"

#include <cstring>

namespace lode::dds {
namespace bridge_detail {

Status Bridge::open(const ParticipantOptions& options) {
  const std::size_t expected = spec_.signals.size() + (spec_.state ? 1 : 0);
  if (tap_.channels().size() != expected) {
    return Status::error("telemetry: the TelemetryTap has " + std::to_string(tap_.channels().size()) +
                         " channels but the spec publishes " + std::to_string(expected) + " topics");
  }
  if (spec_.commands.enabled && control_ == nullptr) {
    return Status::error("telemetry.commands.enabled: no ControlService was given to the bridge");
  }

  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  if (Status s = configure_participant_qos(options, qos); !s) return s;
  domain_ = options.domain;
  // The listener must be there from creation on: it is how command senders are identified.
  participant_ = fdds::DomainParticipantFactory::get_instance()->create_participant(
      static_cast<fdds::DomainId_t>(options.domain), qos, &watcher_, fdds::StatusMask::none());
  if (participant_ == nullptr) {
    return Status::error("telemetry: could not create the DDS participant '" + options.name +
                         "' on domain " + std::to_string(options.domain) + " (transport " +
                         to_string(options.transport.kind) + ")");
  }
  if (Status s = detail::register_types(participant_); !s) return s;
  publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    return Status::error("telemetry: could not create the DDS publisher/subscriber");
  }

  Status status;
  const double rate = pipeline_.rate_hz();
  const auto depth_for = [&](std::uint32_t decimation) {
    if (spec_.history > 0) return static_cast<std::int32_t>(spec_.history);
    return detail::one_second(rate / std::max<std::uint32_t>(decimation, 1), 64);
  };
  for (const auto& signal : spec_.signals) {
    Channel channel;
    channel.writer = make_writer(signal.topic, detail::type_name_signal_sample(),
                                 detail::with_reliability(
                                     detail::writer_qos(Durability::volatile_, depth_for(signal.decimation)),
                                     spec_.reliable),
                                 status);
    channels_.push_back(std::move(channel));
  }
  if (spec_.state) {
    Channel channel;
    channel.state = true;
    channel.pose = spec_.state->pose.size();
    channel.twist = spec_.state->twist ? spec_.state->twist->size() : 0;
    channel.covariance = spec_.state->covariance ? spec_.state->covariance->size() : 0;
    channel.writer = make_writer(spec_.state->topic, detail::type_name_stage_state(),
                                 detail::with_reliability(
                                     detail::writer_qos(Durability::volatile_, depth_for(spec_.state->decimation)),
                                     spec_.reliable),
                                 status);
    channels_.push_back(std::move(channel));
  }
  info_writer_ = make_writer(detail::kSignalsTopic, detail::type_name_signal_info(),
                             detail::writer_qos(Durability::transient_local, 1,
                                                static_cast<std::int32_t>(expected) + 1),
                             status);
  timing_writer_ = make_writer(pipeline_topic(pipeline_.name(), "timing"), detail::type_name_timing(),
                               detail::writer_qos(Durability::volatile_, detail::kTimingDepth), status);
  events_writer_ = make_writer(pipeline_topic(pipeline_.name(), "events"), detail::type_name_event(),
                               detail::writer_qos(Durability::transient_local, detail::kEventsDepth),
                               status);
  if (spec_.commands.enabled) {
    // Transient-local replies: a client whose reply reader matches a moment after its
    // command was answered still gets the answer (it filters by client name and id).
    reply_writer_ = make_writer(pipeline_topic(pipeline_.name(), "reply"), detail::type_name_reply(),
                                detail::writer_qos(Durability::transient_local, detail::kReplyDepth),
                                status);
    const std::string command_topic = pipeline_topic(pipeline_.name(), "command");
    fdds::Topic* topic =
        participant_->create_topic(command_topic, detail::type_name_command(), fdds::TOPIC_QOS_DEFAULT);
    command_reader_ = topic ? subscriber_->create_datareader(
                                  topic,
                                  detail::keep_all_commands(detail::reader_qos(Durability::volatile_, 1), 0.0),
                                  &wakeup_, fdds::StatusMask::data_available())
                            : nullptr;
    if (command_reader_ == nullptr && status) {
      status = Status::error("telemetry: could not create the DDS reader of topic '" + command_topic + "'");
    }
  }
  if (!status) return status;
  if (Status s = publish_signal_info(); !s) return s;
  std::uint32_t step = 0;  // cycles between records: the gcd of the decimations
  for (const auto& c : tap_.channels()) step = std::gcd(step, std::max<std::uint32_t>(c.decimation, 1));
  capture_aim_.set_step_ns(pipeline_.period_ns() * std::max<std::uint32_t>(step, 1));

  publisher_thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "lode-telemetry");
    if (const int priority = spec_.publisher_priority; priority > 0) {
      if (const int rc = set_thread_fifo_priority(priority); rc != 0)
        events_.post(0, 0, "warning",
                     "telemetry.priority " + std::to_string(priority) + ": SCHED_FIFO refused (" + std::strerror(rc) +
                         "): the publisher runs with normal scheduling, and samples leave later when other "
                         "threads keep the CPUs busy");
      else
        publisher_priority_.store(priority, std::memory_order_relaxed);
    }
    publisher_loop();
  });
  if (command_reader_ != nullptr) {
    command_thread_ = std::thread([this] {
      pthread_setname_np(pthread_self(), "lode-commands");
      command_loop();
    });
  }
  return Status::ok();
}

Status Bridge::publish_signal_info() {
  const double rate = pipeline_.rate_hz();
  const auto names_units = [](lode::msg::SignalInfo& info, const SignalRef& ref) {
    if (ref.elements == nullptr) return;
    for (const auto& element : *ref.elements) {
      info.names().push_back(element.name);
      info.units().push_back(element.unit);
    }
  };
  std::vector<lode::msg::SignalInfo>& infos = infos_;
  for (const auto& signal : spec_.signals) {
    lode::msg::SignalInfo info;
    info.topic(signal.topic);
    info.pipeline(pipeline_.name());
    info.block(signal.signal.block);
    info.port(signal.signal.port);
    names_units(info, signal.signal);
    info.rate_hz(signal.rate_hz(rate));
    info.pipeline_rate_hz(rate);
    info.decimation(signal.decimation);
    info.kind("signal");
    info.reliable(spec_.reliable);
    infos.push_back(std::move(info));
  }
  if (spec_.state) {
    const StateSpec& state = *spec_.state;
    lode::msg::SignalInfo info;
    info.topic(state.topic);
    info.pipeline(pipeline_.name());
    info.block(state.pose.block);
    info.port("state");
    names_units(info, state.pose);
    if (state.twist) names_units(info, *state.twist);
    if (state.covariance) names_units(info, *state.covariance);
    info.rate_hz(rate / std::max<std::uint32_t>(state.decimation, 1));
    info.pipeline_rate_hz(rate);
    info.decimation(state.decimation);
    info.kind("state");
    info.pose_size(static_cast<std::uint32_t>(state.pose.size()));
    info.twist_size(static_cast<std::uint32_t>(state.twist ? state.twist->size() : 0));
    info.covariance_size(static_cast<std::uint32_t>(state.covariance ? state.covariance->size() : 0));
    info.reliable(spec_.reliable);
    infos.push_back(std::move(info));
  }
  // Two topics with one key would be one instance: a late joiner would learn only one of
  // them. Across pipelines the odds are negligible (64 bits); within one, refuse.
  std::map<std::uint64_t, const std::string*> seen;
  for (auto& info : infos) {
    info.topic_id(detail::topic_id(info.topic()));
    if (auto [it, fresh] = seen.emplace(info.topic_id(), &info.topic()); !fresh) {
      return Status::error("telemetry: topics '" + *it->second + "' and '" + info.topic() +
                           "' have the same topic_id (XXH64 of the name): rename a block or port");
    }
  }
  for (auto& info : infos) {
    if (!info_writer_->write(&info)) {
      return Status::error("telemetry: could not publish the SignalInfo of '" + info.topic() + "'");
    }
  }
  return Status::ok();
}

void Bridge::publisher_loop() {
  using clock = std::chrono::steady_clock;
  // Timed waits to the microsecond: the default slack of a normal thread (50 us) would add
  // up to that much to every sample's latency.
  prctl(PR_SET_TIMERSLACK, 1000UL, 0UL, 0UL, 0UL);
  const double timing_rate = spec_.timing_rate_hz > 0 ? spec_.timing_rate_hz : 1.0;
  const auto timing_period = std::chrono::duration_cast<clock::duration>(
      std::chrono::duration<double>(1.0 / timing_rate));
  auto next_timing = clock::now() + timing_period;
  // The doorbell wakes us when the RT thread has new samples; publish_period bounds the wait
  // when none comes (events, a stopped or decimated loop).
  const auto publish_period = std::chrono::microseconds(static_cast<long long>(spec_.publish_period_s * 1e6));
  PublishDoorbell& doorbell = tap_.doorbell();
  std::uint32_t seen = doorbell.sequence();
  while (!stopping_.load(std::memory_order_acquire)) {
    std::optional<CaptureAim::Aim> aim;
    {
      std::lock_guard lock(publish_mutex_);  // flush() drains too, and learns from what it drains
      drain_rings();
      // Real clock only: a simulated one has no schedule to aim at.
      if (run_stats_.wake_latency.count() > 0) aim = capture_aim_.next();
      publish_events();
      if (clock::now() >= next_timing) {
        note_namesakes();
        publish_timing();
        next_timing += timing_period;
        if (next_timing < clock::now()) next_timing = clock::now() + timing_period;
      }
    }
    const auto wake_by = std::min(clock::now() + publish_period, next_timing);
    if (aim && aim->wake < wake_by) await_capture(*aim, wake_by, seen);
    // The next samples usually come after wake_by: sleep off the doorbell until then (on it, a
    // ring while this thread's timer is late would cost the RT thread a FUTEX_WAKE).
    else if (aim) std::this_thread::sleep_until(wake_by);
    if (doorbell.sequence() == seen) {
      const auto left = wake_by - clock::now();
      doorbell.wait(seen, std::chrono::duration_cast<std::chrono::nanoseconds>(left));
    }
    seen = doorbell.sequence();
  }
  std::lock_guard lock(publish_mutex_);  // what the last cycles left behind
  drain_rings();
  publish_events();
}

void Bridge::note_namesakes() {
  if (!namesakes_changed_.exchange(false, std::memory_order_acq_rel)) return;
  std::string text;
  {
    std::lock_guard lock(peers_mutex_);
    text = namesakes_ > 0
               ? namesake_live() + ": " + namesake_text_ +
                     ". Subscribers get both pipelines' samples on the same topics, and this pipeline refuses "
                     "commands while it is there: give one of them another `pipeline:` name or "
                     "`telemetry.domain`"
               : "no other pipeline named '" + pipeline_.name() + "' is live on DDS domain " + std::to_string(domain_) +
                     " any more: commands are accepted again";
  }
  events_.post(run_stats_.last_time_ns.load(std::memory_order_relaxed),
               run_stats_.cycles.load(std::memory_order_relaxed), "namesake", text);
}

void Bridge::await_capture(const CaptureAim::Aim& aim, std::chrono::steady_clock::time_point wake_by,
                           std::uint32_t seen) {
  using clock = std::chrono::steady_clock;
  // Awake and polling when the RT thread rings, its ring() is an atomic add and a load, no
  // system call, and the samples leave at once (capture_aim.hpp says why and how long).
  std::this_thread::sleep_until(aim.wake);
  const auto woke = clock::now();
  {
    std::lock_guard lock(publish_mutex_);
    capture_aim_.learn_oversleep(woke - aim.wake);
  }
  const auto spin_end = std::min(woke + capture_aim_.spin_budget(), wake_by);
  PublishDoorbell& doorbell = tap_.doorbell();
  while (doorbell.sequence() == seen && clock::now() < spin_end) cpu_relax();
  // A late capture: sleep past the usual latest one, then look every spin_budget() until the
  // next cycle is due, before waiting on the doorbell: asleep on it, the publisher costs the
  // RT thread's ring a FUTEX_WAKE (microseconds in a VM); these naps cost the publisher a
  // timer wake-up each, for the few captures later than the 98th percentile.
  if (doorbell.sequence() == seen && aim.late < wake_by) std::this_thread::sleep_until(aim.late);
  const auto nap = std::max<clock::duration>(capture_aim_.spin_budget(), std::chrono::microseconds(5));
  const auto give_up = std::min(aim.next_cycle, wake_by);
  for (auto now = clock::now(); doorbell.sequence() == seen && now < give_up; now = clock::now())
    std::this_thread::sleep_until(std::min(now + nap, give_up));
}

void Bridge::drain_rings() {
  auto& tap_channels = tap_.channels();
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    Channel& channel = channels_[i];
    SampleRing& ring = *tap_channels[i].ring;
    SampleHeader header;
    while (const double* values = ring.front(header)) {
      capture_aim_.learn_capture(header.stamp_ns, header.captured_ns);
      bool ok = false;
      if (!channel.state) {
        auto& s = channel.sample;
        s.cycle(header.cycle);
        s.stamp_ns(header.stamp_ns);
        s.captured_ns(header.captured_ns);
        s.values().assign(values, values + ring.width());
        ok = channel.writer->write(&s);
      } else {
        auto& s = channel.stage;
        s.cycle(header.cycle);
        s.stamp_ns(header.stamp_ns);
        s.captured_ns(header.captured_ns);
        const double* twist = values + channel.pose;
        const double* covariance = twist + channel.twist;
        s.pose().assign(values, twist);
        s.twist().assign(twist, covariance);
        s.covariance().assign(covariance, covariance + channel.covariance);
        ok = channel.writer->write(&s);
      }
      ring.pop();
      if (ok) {
        published_.fetch_add(1, std::memory_order_relaxed);
      } else {
        write_failures_.fetch_add(1, std::memory_order_relaxed);
      }
    }
  }
}

void Bridge::publish_timing() {
  lode::msg::TimingStats t;
  t.cycle(run_stats_.cycles.load(std::memory_order_relaxed));
  t.stamp_ns(run_stats_.last_time_ns.load(std::memory_order_relaxed));
  t.rate_hz(pipeline_.rate_hz());
  // Only a real clock measures wake-up latency.
  t.real_clock(run_stats_.wake_latency.count() > 0);
  t.executed(run_stats_.executed.load(std::memory_order_relaxed));
  t.overruns(run_stats_.overruns.load(std::memory_order_relaxed));
  t.missed_periods(run_stats_.missed_periods.load(std::memory_order_relaxed));
  t.telemetry_dropped(tap_.dropped() + write_failures_.load(std::memory_order_relaxed));
  t.rt_log_dropped(rt_log_ring().dropped());
  t.wake_latency(summarize("wake_latency", run_stats_.wake_latency));
  t.cycle_time(summarize("cycle_time", run_stats_.cycle_time));
  for (const auto& op : pipeline_.ops()) {
    if (op.exec_time) t.blocks().push_back(summarize(op.label, *op.exec_time));
  }
  timing_writer_->write(&t);
}

void Bridge::publish_events() {
  for (const Event& event : events_.since(event_cursor_)) {
    lode::msg::Event e;
    e.cycle(event.cycle);
    e.stamp_ns(event.time_ns);
    e.kind(event.kind);
    e.text(event.text);
    events_writer_->write(&e);
  }
}

}  // namespace bridge_detail

Expected<std::unique_ptr<TelemetryBridge>> TelemetryBridge::start(
    const Pipeline& pipeline, const TelemetrySpec& spec, TelemetryTap& tap, const RunStats& stats,
    EventLog& events, ControlService* control, const ParticipantOptions& options) {
  auto bridge = std::make_unique<bridge_detail::Bridge>(pipeline, spec, tap, stats, events, control);
  if (Status s = bridge->open(options); !s) return s;  // the destructor deletes what exists
  return std::unique_ptr<TelemetryBridge>(std::move(bridge));
}

}  // namespace lode::dds
