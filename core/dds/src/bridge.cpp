// The telemetry bridge: two non-RT threads and the DDS entities of one pipeline.
//
// "lode-telemetry" drains the TelemetryTap's rings every millisecond and writes the
// samples, the timing statistics (every 1/timing_rate_hz) and new events. "lode-commands"
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
#include "lode/dds/bridge.hpp"

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/rtps/participant/ParticipantDiscoveryInfo.h>
#include <fastrtps/utils/IPLocator.h>

#include "command_request.hpp"
#include "common.hpp"
#include "lode/rt_log.hpp"
#include "lode_msgs.h"

namespace lode::dds {

namespace {

namespace fdds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;
using detail::Durability;

/// What discovery told us about another participant: what `allow_participants` and
/// `allow_hosts` are checked against.
struct Peer {
  std::string name;
  std::vector<std::string> hosts;  ///< IPv4 addresses of its unicast locators
  bool shared_memory = false;      ///< reachable over shared memory, i.e. on this host
};

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

bool contains(const std::vector<std::string>& items, const std::string& item) {
  return std::find(items.begin(), items.end(), item) != items.end();
}

lode::msg::LatencySummary summarize(const std::string& name, const Histogram& h) {
  lode::msg::LatencySummary s;
  const auto us = [](std::int64_t ns) { return static_cast<double>(ns) / 1000.0; };
  s.name(name);
  s.count(h.count());
  s.p50_us(us(h.percentile(0.50)));
  s.p90_us(us(h.percentile(0.90)));
  s.p99_us(us(h.percentile(0.99)));
  s.p999_us(us(h.percentile(0.999)));
  s.max_us(us(h.max()));
  s.mean_us(h.mean() / 1000.0);
  return s;
}

class Bridge;

class ParticipantWatcher final : public fdds::DomainParticipantListener {
 public:
  explicit ParticipantWatcher(Bridge& bridge) : bridge_(bridge) {}
  void on_participant_discovery(fdds::DomainParticipant* participant,
                                rtps::ParticipantDiscoveryInfo&& info) override;

 private:
  Bridge& bridge_;
};

class CommandWakeup final : public fdds::DataReaderListener {
 public:
  explicit CommandWakeup(Bridge& bridge) : bridge_(bridge) {}
  void on_data_available(fdds::DataReader* reader) override;

 private:
  Bridge& bridge_;
};

class Bridge final : public TelemetryBridge {
 public:
  Bridge(const Pipeline& pipeline, const TelemetrySpec& spec, TelemetryTap& tap,
         const RunStats& stats, EventLog& events, ControlService* control)
      : pipeline_(pipeline), spec_(spec), tap_(tap), run_stats_(stats), events_(events),
        control_(control), watcher_(*this), wakeup_(*this) {}

  ~Bridge() override { stop(); }

  Status open(const ParticipantOptions& options);

  void flush() override {
    std::lock_guard lock(publish_mutex_);
    drain_rings();
    publish_events();
    publish_timing();  // the statistics as they stand now (end of run)
  }

  [[nodiscard]] std::size_t matched_readers() const override {
    std::size_t total = 0;
    for (const auto& channel : channels_) {
      fdds::PublicationMatchedStatus status;
      if (channel.writer->get_publication_matched_status(status) == ReturnCode_t::RETCODE_OK) {
        total += static_cast<std::size_t>(std::max(status.current_count, 0));
      }
    }
    return total;
  }

  [[nodiscard]] BridgeStats stats() const override {
    BridgeStats s;
    s.published = published_.load(std::memory_order_relaxed);
    s.ring_dropped = tap_.dropped() + write_failures_.load(std::memory_order_relaxed);
    s.commands_accepted = commands_accepted_.load(std::memory_order_relaxed);
    s.commands_refused = commands_refused_.load(std::memory_order_relaxed);
    return s;
  }

  void stop() override {
    {
      std::lock_guard lock(wake_mutex_);
      if (stopped_) return;
      stopped_ = true;
    }
    wake_.notify_all();
    if (publisher_thread_.joinable()) publisher_thread_.join();
    if (command_thread_.joinable()) command_thread_.join();
    // Reliable readers get what was written last (the final samples, the stop event, the
    // last reply) before the participant goes: up to 0.5 s per writer, usually microseconds.
    const eprosima::fastrtps::Duration_t ack_wait(0, 500'000'000);
    for (auto& channel : channels_)
      if (channel.writer != nullptr) channel.writer->wait_for_acknowledgments(ack_wait);
    for (auto* w : {timing_writer_, events_writer_, reply_writer_})
      if (w != nullptr) w->wait_for_acknowledgments(ack_wait);
    if (info_writer_ != nullptr) {
      // Tell subscribers these topics are gone now, not when our lease expires.
      for (auto& info : infos_) info_writer_->dispose(&info, fdds::HANDLE_NIL);
      info_writer_->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(0, 200'000'000));
      info_writer_ = nullptr;
    }
    if (participant_ != nullptr) {
      participant_->set_listener(nullptr);
      delete_participant(participant_);
      participant_ = nullptr;
    }
    channels_.clear();  // their writers are gone: matched_readers() is 0 from now on
  }

  // Listener entry points (Fast DDS threads): record and wake, nothing else.
  void participant_changed(const rtps::ParticipantDiscoveryInfo& info) {
    const auto& data = info.info;
    std::lock_guard lock(peers_mutex_);
    if (info.status == rtps::ParticipantDiscoveryInfo::REMOVED_PARTICIPANT ||
        info.status == rtps::ParticipantDiscoveryInfo::DROPPED_PARTICIPANT) {
      peers_.erase(data.m_guid.guidPrefix);
      return;
    }
    Peer peer;
    peer.name = data.m_participantName.to_string();
    const auto add = [&peer](const rtps::Locator_t& locator) {
      if (locator.kind == LOCATOR_KIND_SHM) {
        peer.shared_memory = true;
      } else if (locator.kind == LOCATOR_KIND_UDPv4 || locator.kind == LOCATOR_KIND_TCPv4) {
        if (rtps::IPLocator::isAny(locator)) return;
        const std::string ip = rtps::IPLocator::toIPv4string(locator);
        if (!contains(peer.hosts, ip)) peer.hosts.push_back(ip);
      }
    };
    for (const auto& locator : data.metatraffic_locators.unicast) add(locator);
    for (const auto& locator : data.default_locators.unicast) add(locator);
    peers_[data.m_guid.guidPrefix] = std::move(peer);
    peers_changed_.notify_all();
  }

  void command_available() {
    {
      std::lock_guard lock(wake_mutex_);
      commands_pending_ = true;
    }
    wake_.notify_all();
  }

 private:
  struct Channel {
    fdds::DataWriter* writer = nullptr;
    bool state = false;
    std::size_t pose = 0, twist = 0, covariance = 0;  ///< state layout
    lode::msg::SignalSample sample;                   ///< reused: no allocation per write
    lode::msg::StageState stage;
  };

  fdds::DataWriter* make_writer(const std::string& topic_name, const char* type,
                                const fdds::DataWriterQos& qos, Status& status) {
    fdds::Topic* topic = participant_->create_topic(topic_name, type, fdds::TOPIC_QOS_DEFAULT);
    fdds::DataWriter* writer = topic ? publisher_->create_datawriter(topic, qos) : nullptr;
    if (writer == nullptr && status) {
      status = Status::error("telemetry: could not create the DDS writer of topic '" + topic_name + "'");
    }
    return writer;
  }

  Status publish_signal_info();
  void publisher_loop();
  void command_loop();
  void drain_rings();
  void publish_timing();
  void publish_events();
  void handle_command(const lode::msg::Command& command, const fdds::SampleInfo& info);
  void write_reply(const lode::msg::Command& command, const ControlReply& reply);

  const Pipeline& pipeline_;
  const TelemetrySpec& spec_;
  TelemetryTap& tap_;
  const RunStats& run_stats_;
  EventLog& events_;
  ControlService* control_;

  ParticipantWatcher watcher_;
  CommandWakeup wakeup_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  fdds::DataWriter* info_writer_ = nullptr;
  fdds::DataWriter* timing_writer_ = nullptr;
  fdds::DataWriter* events_writer_ = nullptr;
  fdds::DataWriter* reply_writer_ = nullptr;
  fdds::DataReader* command_reader_ = nullptr;
  std::vector<Channel> channels_;
  std::vector<lode::msg::SignalInfo> infos_;  ///< as published (disposed on stop)

  std::mutex publish_mutex_;  ///< one consumer of the rings at a time (thread or flush())
  std::size_t event_cursor_ = 0;

  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stopped_ = false;
  bool commands_pending_ = false;
  std::thread publisher_thread_;
  std::thread command_thread_;

  std::mutex peers_mutex_;
  std::condition_variable peers_changed_;
  std::map<rtps::GuidPrefix_t, Peer> peers_;

  std::atomic<std::uint64_t> published_{0};
  std::atomic<std::uint64_t> write_failures_{0};
  std::atomic<std::uint64_t> commands_accepted_{0};
  std::atomic<std::uint64_t> commands_refused_{0};
};

void ParticipantWatcher::on_participant_discovery(fdds::DomainParticipant* /*participant*/,
                                                  rtps::ParticipantDiscoveryInfo&& info) {
  bridge_.participant_changed(info);
}

void CommandWakeup::on_data_available(fdds::DataReader* /*reader*/) { bridge_.command_available(); }

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

  publisher_thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "lode-telemetry");
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
  for (auto& info : infos) {
    if (!info_writer_->write(&info)) {
      return Status::error("telemetry: could not publish the SignalInfo of '" + info.topic() + "'");
    }
  }
  return Status::ok();
}

void Bridge::publisher_loop() {
  using clock = std::chrono::steady_clock;
  const double timing_rate = spec_.timing_rate_hz > 0 ? spec_.timing_rate_hz : 1.0;
  const auto timing_period = std::chrono::duration_cast<clock::duration>(
      std::chrono::duration<double>(1.0 / timing_rate));
  auto next_timing = clock::now() + timing_period;
  std::unique_lock wake_lock(wake_mutex_);
  // The RT thread cannot wake us (that would be a system call): poll. The period bounds
  // the added latency (uniform in [0, period]) against the CPU cost of waking up.
  const auto publish_period = std::chrono::microseconds(static_cast<long long>(spec_.publish_period_s * 1e6));
  while (!stopped_) {
    wake_lock.unlock();
    {
      std::lock_guard lock(publish_mutex_);
      drain_rings();
      publish_events();
      if (clock::now() >= next_timing) {
        publish_timing();
        next_timing += timing_period;
        if (next_timing < clock::now()) next_timing = clock::now() + timing_period;
      }
    }
    wake_lock.lock();
    wake_.wait_for(wake_lock, publish_period, [this] { return stopped_; });
  }
  wake_lock.unlock();
  std::lock_guard lock(publish_mutex_);  // what the last cycles left behind
  drain_rings();
  publish_events();
}

void Bridge::drain_rings() {
  auto& tap_channels = tap_.channels();
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    Channel& channel = channels_[i];
    SampleRing& ring = *tap_channels[i].ring;
    SampleHeader header;
    while (const double* values = ring.front(header)) {
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

void Bridge::command_loop() {
  std::unique_lock wake_lock(wake_mutex_);
  while (true) {
    wake_.wait_for(wake_lock, std::chrono::milliseconds(100),
                   [this] { return stopped_ || commands_pending_; });
    if (stopped_) return;
    commands_pending_ = false;
    wake_lock.unlock();
    lode::msg::Command command;
    fdds::SampleInfo info;
    while (command_reader_->take_next_sample(&command, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) handle_command(command, info);
    }
    wake_lock.lock();
  }
}

void Bridge::handle_command(const lode::msg::Command& command, const fdds::SampleInfo& info) {
  rtps::GuidPrefix_t sender = info.sample_identity.writer_guid().guidPrefix;
  if (sender == rtps::GuidPrefix_t::unknown()) sender = rtps::iHandle2GUID(info.publication_handle).guidPrefix;

  const CommandAccess& access = spec_.commands;
  const bool open_to_all = access.allow_participants.empty() && access.allow_hosts.empty();
  // Discovery announces a participant before its endpoints match; the short wait only
  // covers the listener thread not having run yet.
  Peer peer;
  bool known = false;
  if (!open_to_all) {
    std::unique_lock lock(peers_mutex_);
    known = peers_changed_.wait_for(lock, std::chrono::milliseconds(500),
                                    [&] { return peers_.count(sender) > 0; });
    if (known) peer = peers_.at(sender);
  }
  const bool name_ok = access.allow_participants.empty() ||
                       (known && contains(access.allow_participants, peer.name));
  bool host_ok = access.allow_hosts.empty();
  for (const auto& host : peer.hosts) host_ok = host_ok || contains(access.allow_hosts, host);
  // A shared-memory peer is on this host: it is "127.0.0.1".
  host_ok = host_ok || (peer.shared_memory && contains(access.allow_hosts, "127.0.0.1"));

  if (!open_to_all && !(known && name_ok && host_ok)) {
    std::vector<std::string> hosts = peer.hosts;
    if (peer.shared_memory) hosts.emplace_back("shared memory");
    std::string fields;
    if (!name_ok) fields = "telemetry.commands.allow_participants";
    if (!host_ok) fields += std::string(fields.empty() ? "" : " and ") + "telemetry.commands.allow_hosts";
    ControlReply reply;
    reply.id = command.id();
    reply.ok = false;
    reply.message = known ? "refused: participant '" + peer.name + "' from hosts [" + join(hosts) +
                                "] is not allowed to command this pipeline (see " + fields + ")"
                          : "refused: the sender (calling itself '" + command.client() +
                                "') was not discovered as a participant, so telemetry.commands.allow_* "
                                "cannot be checked";
    commands_refused_.fetch_add(1, std::memory_order_relaxed);
    events_.post_limited(run_stats_.last_time_ns.load(std::memory_order_relaxed),
                         run_stats_.cycles.load(std::memory_order_relaxed), "command_refused",
                 command.kind() + " " + command.block() + (command.name().empty() ? "" : "." + command.name()) +
                     ": " + reply.message);
    write_reply(command, reply);
    return;
  }

  // The discovered identity when access is checked, else what the sender declares.
  const ControlRequest request = detail::command_request(command, known ? peer.name : command.client());
  commands_accepted_.fetch_add(1, std::memory_order_relaxed);
  ControlReply reply = control_->handle(request);
  reply.id = command.id();
  write_reply(command, reply);
}

void Bridge::write_reply(const lode::msg::Command& command, const ControlReply& reply) {
  lode::msg::Reply r;
  r.client(command.client());
  r.id(command.id());
  r.ok(reply.ok);
  r.message(reply.message);
  r.value(reply.value);
  reply_writer_->write(&r);
}

}  // namespace

Expected<std::unique_ptr<TelemetryBridge>> TelemetryBridge::start(
    const Pipeline& pipeline, const TelemetrySpec& spec, TelemetryTap& tap, const RunStats& stats,
    EventLog& events, ControlService* control, const ParticipantOptions& options) {
  auto bridge = std::make_unique<Bridge>(pipeline, spec, tap, stats, events, control);
  if (Status s = bridge->open(options); !s) return s;  // the destructor deletes what exists
  return std::unique_ptr<TelemetryBridge>(std::move(bridge));
}

}  // namespace lode::dds
