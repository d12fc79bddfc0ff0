// Internal to the telemetry bridge: the Bridge class, shared by its publishing side
// (bridge.cpp) and its command side (bridge_commands.cpp).
#pragma once

#include "lode/dds/bridge.hpp"

#include <pthread.h>
#include <sys/prctl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
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

#include "capture_aim.hpp"
#include "command_request.hpp"
#include "common.hpp"
#include "lode/sdk/rt_log.hpp"
#include "lode_msgs.h"

namespace lode::dds::bridge_detail {

namespace fdds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;
using detail::Durability;

/// What discovery told us about another participant: what `allow_participants` and
/// `allow_hosts` are checked against.
struct Peer {
  std::string name;
  std::vector<std::string> hosts;  ///< IPv4 addresses of its unicast locators
  bool shared_memory = false;      ///< reachable over shared memory, i.e. on this host

  /// Where it is reachable, for messages: "192.168.10.6, shared memory".
  [[nodiscard]] std::string where() const;
};

inline std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

inline std::string Peer::where() const {
  std::vector<std::string> places = hosts;
  if (shared_memory) places.emplace_back("shared memory");
  return join(places);
}

inline bool contains(const std::vector<std::string>& items, const std::string& item) {
  return std::find(items.begin(), items.end(), item) != items.end();
}

inline lode::msg::LatencySummary summarize(const std::string& name, const Histogram& h) {
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
    s.commands_malformed = commands_malformed_.load(std::memory_order_relaxed);
    s.publisher_priority = publisher_priority_.load(std::memory_order_relaxed);
    return s;
  }

  void stop() override {
    {
      std::lock_guard lock(wake_mutex_);
      if (stopped_) return;
      stopped_ = true;
    }
    stopping_.store(true, std::memory_order_release);
    tap_.doorbell().wake_all();
    wake_.notify_all();
    if (publisher_thread_.joinable()) publisher_thread_.join();
    if (command_thread_.joinable()) command_thread_.join();
    if (control_) control_->join_workers();  // a swap ends with the run: its wait sees the loop stop
    if (command_reader_ != nullptr) note_malformed_commands();  // those dropped since its last look
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
      recount_namesakes();
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
    recount_namesakes();
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

  /// Other live pipelines of this one's name on this domain (another rig or user started the
  /// same configuration): their topics are this pipeline's topics, so subscribers get both
  /// pipelines' samples mixed, and a command would reach both. Under peers_mutex_.
  void recount_namesakes() {
    std::size_t count = 0;
    std::string who;
    for (const auto& [prefix, peer] : peers_) {
      const auto name = pipeline_of_participant(peer.name);
      if (!name || *name != pipeline_.name()) continue;
      ++count;
      who += (who.empty() ? "" : "; ") + peer.name + " [" + peer.where() + "]";
    }
    if (count == namesakes_) return;
    namesakes_ = count;
    namesake_text_ = who;
    namesakes_changed_.store(true, std::memory_order_release);
  }
  /// Posts a "namesake" event when namesakes came or all went (publisher thread).
  void note_namesakes();
  /// "another pipeline named 'P' is live on DDS domain D": the event's and a refusal's start.
  [[nodiscard]] std::string namesake_live() const {
    return "another pipeline named '" + pipeline_.name() + "' is live on DDS domain " + std::to_string(domain_);
  }

  Status publish_signal_info();
  void publisher_loop();
  void command_loop();
  void drain_rings();
  /// Sleep until just before the next records are due, then poll the doorbell briefly.
  void await_capture(const CaptureAim::Aim& aim, std::chrono::steady_clock::time_point wake_by,
                     std::uint32_t seen);
  void publish_timing();
  void publish_events();
  void handle_command(const lode::msg::Command& command, const fdds::SampleInfo& info);
  void write_reply(const lode::msg::Command& command, const ControlReply& reply);
  /// Replies "not done" with `message` and counts it (a refused-command event, rate limited).
  void refuse(const lode::msg::Command& command, const std::string& message);
  void note_malformed_commands();

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

  // When the RT thread copies a cycle's values, learnt from the records drained (under
  // publish_mutex_, as the rings).
  CaptureAim capture_aim_;
  std::atomic<bool> stopping_{false};  ///< the publisher thread's stop flag

  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stopped_ = false;
  bool commands_pending_ = false;
  std::thread publisher_thread_;
  std::thread command_thread_;

  std::mutex peers_mutex_;
  std::condition_variable peers_changed_;
  std::map<rtps::GuidPrefix_t, Peer> peers_;
  std::size_t namesakes_ = 0;   ///< recount_namesakes(), under peers_mutex_
  std::string namesake_text_;   ///< who they are, under peers_mutex_
  std::atomic<bool> namesakes_changed_{false};
  int domain_ = 0;

  std::atomic<std::uint64_t> published_{0};
  std::atomic<std::uint64_t> write_failures_{0};
  std::atomic<std::uint64_t> commands_accepted_{0};
  std::atomic<std::uint64_t> commands_refused_{0};
  std::atomic<std::uint64_t> commands_malformed_{0};
  std::atomic<int> publisher_priority_{0};  ///< set by the publisher thread as it starts
};

inline void ParticipantWatcher::on_participant_discovery(fdds::DomainParticipant* /*participant*/,
                                                         rtps::ParticipantDiscoveryInfo&& info) {
  bridge_.participant_changed(info);
  detail::hold_reply_to_new_participant(info);
}

inline void CommandWakeup::on_data_available(fdds::DataReader* /*reader*/) { bridge_.command_available(); }

}  // namespace lode::dds::bridge_detail
