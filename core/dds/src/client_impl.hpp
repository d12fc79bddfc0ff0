// Internal to the DDS client: the ClientImpl class behind lode::dds::Client and the listener
// plumbing its parts share. Its methods live by job: the client's participant and lifetime
// (client.cpp), what is live (client_discovery.cpp: `lode/signals` metadata, pipelines,
// resolving a name), subscriptions (client_subscriptions.cpp: samples, events, timing) and
// request/reply commands (client_commands.cpp).
//
// Subscriptions run their callback on the Fast DDS listener thread of their reader, under
// a per-subscription mutex (a Gate): destroying a Subscription waits for a running callback
// and no callback starts afterwards. Subscriptions must be destroyed before their Client.
#pragma once

#include "lode/dds/client.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <type_traits>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>

#include "common.hpp"
#include "local_delivery.hpp"
#include "lode_msgs.h"

namespace lode::dds::client_detail {

namespace fdds = eprosima::fastdds::dds;
using detail::Durability;
using Clock = std::chrono::steady_clock;

/// Shared between a subscription and its listeners: closing waits for a running callback.
struct Gate {
  std::mutex mutex;
  bool closed = false;
  std::atomic<std::uint64_t> received{0};
};

class TakeListener final : public fdds::DataReaderListener {
 public:
  using Drain = std::function<void(fdds::DataReader*, Gate&)>;
  TakeListener(std::shared_ptr<Gate> gate, Drain drain) : gate_(std::move(gate)), drain_(std::move(drain)) {}
  void on_data_available(fdds::DataReader* reader) override {
    std::lock_guard lock(gate_->mutex);
    if (!gate_->closed && !retired_) drain_(reader, *gate_);
  }
  /// From now on this reader's samples are left where they are (another reader of the
  /// subscription takes its place). Under the gate's mutex.
  void retire() { retired_ = true; }

 private:
  std::shared_ptr<Gate> gate_;
  Drain drain_;
  bool retired_ = false;  ///< guarded by the gate's mutex
};

/// Every sample `reader` holds, in order, each valid one handed to `use` (the others only
/// announce that an instance was disposed or its writer left), with its SampleInfo where
/// `use` takes it.
template <typename Message, typename Use>
void take_valid(fdds::DataReader* reader, Use&& use) {
  Message message;
  fdds::SampleInfo info;
  while (reader->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
    if (!info.valid_data) continue;
    if constexpr (std::is_invocable_v<Use, const Message&, const fdds::SampleInfo&>) use(message, info);
    else use(message);
  }
}

/// The `lode/signals` reader's listener: new metadata, and writers that went away.
class InfoListener final : public fdds::DataReaderListener {
 public:
  InfoListener(std::shared_ptr<Gate> gate, std::function<void(fdds::DataReader*)> on_data,
               std::function<void(const fdds::InstanceHandle_t&)> on_writer_gone)
      : gate_(std::move(gate)), on_data_(std::move(on_data)), on_writer_gone_(std::move(on_writer_gone)) {}
  void on_data_available(fdds::DataReader* reader) override {
    std::lock_guard lock(gate_->mutex);
    if (!gate_->closed) on_data_(reader);
  }
  void on_subscription_matched(fdds::DataReader* /*reader*/, const fdds::SubscriptionMatchedStatus& status) override {
    std::lock_guard lock(gate_->mutex);
    if (!gate_->closed && status.current_count_change < 0) on_writer_gone_(status.last_publication_handle);
  }

 private:
  std::shared_ptr<Gate> gate_;
  std::function<void(fdds::DataReader*)> on_data_;
  std::function<void(const fdds::InstanceHandle_t&)> on_writer_gone_;
};

/// Which pipelines' bridges this participant has discovered (by their participant names),
/// as a set to poll. Participant discovery comes first; a
/// pipeline's topics and its SignalInfo arrive later, and on a loaded host much later.
class PipelineParticipants final : public fdds::DomainParticipantListener {
 public:
  void on_participant_discovery(fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override;
  std::set<std::string> pipelines() const;
  /// Live participants that are the bridge of a pipeline of this name.
  std::size_t count(const std::string& pipeline) const;
  /// Whether every live bridge of `pipeline` (at least one) can deliver through the shared
  /// memory of this process, whose participant is `own` (see local_delivery.hpp).
  bool shared_memory_reaches_us(const std::string& pipeline, const eprosima::fastrtps::rtps::GuidPrefix_t& own) const;

 private:
  struct Bridge {
    std::string pipeline;
    std::optional<std::uint32_t> uid;  ///< as the participant announced it
  };
  mutable std::mutex mutex_;
  std::map<eprosima::fastrtps::rtps::GuidPrefix_t, Bridge> live_;
};

class ClientImpl;

/// Readers of one subscription, deleted (after closing the gate) when it is destroyed.
class ReaderSubscription final : public Subscription {
 public:
  ReaderSubscription(ClientImpl& client, std::shared_ptr<Gate> gate) : client_(client), gate_(std::move(gate)) {}
  ~ReaderSubscription() override;
  [[nodiscard]] std::uint64_t received() const override {
    return gate_->received.load(std::memory_order_relaxed);
  }
  void add(fdds::DataReader* reader, std::unique_ptr<TakeListener> listener);
  /// The readers so far deliver nothing more (they are deleted with the subscription).
  void retire_readers();
  /// A thread that runs `poll` every 200 ms: for "every pipeline", a reader per newly seen
  /// pipeline; for a shared-memory reader, its replacement when that can no longer work.
  void watch(std::function<void()> poll);

 private:
  struct Entry {
    fdds::DataReader* reader;
    std::unique_ptr<TakeListener> listener;
  };
  ClientImpl& client_;
  std::shared_ptr<Gate> gate_;
  std::mutex readers_mutex_;
  std::vector<Entry> readers_;
  std::thread watcher_;
  std::mutex stop_mutex_;
  std::condition_variable stop_changed_;
  bool stop_ = false;
};

/// Command writer and reply reader of one pipeline, kept for the client's lifetime.
struct CommandChannel {
  fdds::DataWriter* writer = nullptr;
  fdds::DataReader* reader = nullptr;
  std::unique_ptr<TakeListener> listener;
};

class ClientImpl final : public Client {
 public:
  explicit ClientImpl(std::string name);
  ~ClientImpl() override;

  Status open(const ParticipantOptions& options);

  // client_discovery.cpp
  std::vector<SignalMeta> signals(std::chrono::milliseconds wait) override;
  std::vector<std::string> pipelines(std::chrono::milliseconds wait) override;
  [[nodiscard]] std::size_t namesakes(const std::string& pipeline) const override {
    return participants_.count(pipeline);
  }
  Expected<SignalMeta> resolve(const std::string& what, std::chrono::milliseconds wait) override;

  // client_subscriptions.cpp
  Expected<std::unique_ptr<Subscription>> subscribe(
      const SignalMeta& meta, std::function<void(const SignalMeta&, const Sample&)> on_sample) override;
  Expected<std::unique_ptr<Subscription>> subscribe_events(
      const std::string& pipeline, std::function<void(const EventSample&)> on_event) override;
  Expected<std::unique_ptr<Subscription>> subscribe_timing(
      const std::string& pipeline, std::function<void(const TimingSample&)> on_timing) override;

  // client_commands.cpp
  Expected<ControlReply> command(const std::string& pipeline, ControlRequest request,
                                 std::chrono::milliseconds timeout) override;

  // client.cpp
  [[nodiscard]] std::uint64_t malformed_samples() const override;

  fdds::Topic* find_or_create_topic(const std::string& name, const char* type);
  void delete_reader(fdds::DataReader* reader) { subscriber_->delete_datareader(reader); }

 private:
  using DrainFor = std::function<TakeListener::Drain(const std::string& pipeline)>;

  Status add_reader(ReaderSubscription& subscription, fdds::Topic* topic, const fdds::DataReaderQos& qos,
                    std::shared_ptr<Gate> gate, TakeListener::Drain drain);
  /// lode/<p>/<what> of one pipeline, or of every pipeline as its SignalInfo appears.
  Expected<std::unique_ptr<Subscription>> subscribe_pipeline_topic(const std::string& pipeline,
                                                                   const std::string& what, const char* type,
                                                                   const fdds::DataReaderQos& qos,
                                                                   DrainFor drain_for);
  Expected<CommandChannel*> command_channel(const std::string& pipeline);
  void take_info(fdds::DataReader* reader);
  /// A SignalInfo writer unmatched (its pipeline stopped without disposing, or its
  /// participant's lease expired): its topics are no longer live.
  void forget_writer(const fdds::InstanceHandle_t& writer);
  /// Forms: "lode/p/b/port", "p/b/port", "p/b.port", "b.port", "p/state", "state".
  std::vector<SignalMeta> match(const std::string& what) const;

  std::string name_;
  TransportSpec::Kind transport_ = TransportSpec::Kind::loopback;
  /// The shared-memory port this client's sample readers announce alone where a pipeline can
  /// deliver there (claimed at the first such reader, held until the client is destroyed,
  /// after its participant; see local_delivery.hpp).
  std::mutex shared_memory_mutex_;
  bool shared_memory_tried_ = false;
  std::optional<detail::SharedMemoryPort> shared_memory_port_;
  PipelineParticipants participants_;  // outlives participant_ (deleted in the destructor's body)
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  std::mutex topics_mutex_;

  std::shared_ptr<Gate> info_gate_;
  std::unique_ptr<InfoListener> info_listener_;
  fdds::DataReader* info_reader_ = nullptr;
  mutable std::mutex signals_mutex_;
  std::condition_variable signals_changed_;
  std::map<std::string, SignalMeta> signals_;
  std::map<fdds::InstanceHandle_t, std::string> handles_;       ///< instance -> topic
  std::map<std::string, fdds::InstanceHandle_t> writers_;        ///< topic -> its writer

  std::mutex commands_mutex_;
  std::map<std::string, CommandChannel> commands_;
  std::shared_ptr<Gate> replies_gate_;
  std::mutex replies_mutex_;
  std::condition_variable replies_changed_;
  std::deque<lode::msg::Reply> replies_;
  std::uint64_t next_id_ = 0;
  bool closing_ = false;
};

}  // namespace lode::dds::client_detail
