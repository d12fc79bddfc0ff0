// The client side: metadata of every live signal (transient-local `lode/signals`),
// subscriptions that hand each sample to a callback, and request/reply commands.
//
// Subscriptions run their callback on the Fast DDS listener thread of their reader, under
// a per-subscription mutex: destroying a Subscription waits for a running callback and
// no callback starts afterwards. Subscriptions must be destroyed before their Client.
//
// Events/timing of "every pipeline" (empty name): a thread of the subscription looks at
// the pipelines known from `lode/signals` every 200 ms and adds a reader for each new one;
// a pipeline that publishes no signal and no state has no SignalInfo and is not found.
//
// Commands: each pipeline gets one command writer and one transient-local reply reader for
// the client's lifetime. Ids on the wire are unique per client (time-seeded), so a reply
// left in a reply writer's history by an earlier client of the same name never matches;
// the reply handed back carries the caller's request.id.
#include "lode/dds/client.hpp"
#include "lode/sdk/clock.hpp"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <thread>

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
#include "lode_msgs.h"

namespace lode::dds {

namespace {

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
    if (!gate_->closed) drain_(reader, *gate_);
  }

 private:
  std::shared_ptr<Gate> gate_;
  Drain drain_;
};

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

SignalMeta meta_from(const lode::msg::SignalInfo& info) {
  SignalMeta m;
  m.topic = info.topic();
  m.pipeline = info.pipeline();
  m.block = info.block();
  m.port = info.port();
  m.kind = info.kind();
  m.names = info.names();
  m.units = info.units();
  m.rate_hz = info.rate_hz();
  m.pipeline_rate_hz = info.pipeline_rate_hz();
  m.decimation = info.decimation();
  m.pose_size = info.pose_size();
  m.twist_size = info.twist_size();
  m.covariance_size = info.covariance_size();
  m.reliable = info.reliable();
  return m;
}

TimingSample::Row row_from(const lode::msg::LatencySummary& s) {
  return {s.name(), s.count(), s.p50_us(), s.p90_us(), s.p99_us(), s.p999_us(), s.max_us(), s.mean_us()};
}

std::string topic_list(const std::vector<SignalMeta>& metas) {
  std::string out;
  for (const auto& m : metas) out += (out.empty() ? "" : ", ") + m.topic;
  return out.empty() ? "none" : out;
}

/// Which pipelines' bridges this participant has discovered (by their participant names),
/// as a set to poll. Participant discovery comes first; a
/// pipeline's topics and its SignalInfo arrive later, and on a loaded host much later.
class PipelineParticipants final : public fdds::DomainParticipantListener {
 public:
  void on_participant_discovery(fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override {
    using Info = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
    const auto pipeline = pipeline_of_participant(info.info.m_participantName.to_string());
    if (!pipeline) return;
    std::lock_guard lock(mutex_);
    if (info.status == Info::REMOVED_PARTICIPANT || info.status == Info::DROPPED_PARTICIPANT)
      live_.erase(info.info.m_guid.guidPrefix);
    else
      live_[info.info.m_guid.guidPrefix] = *pipeline;
  }
  std::set<std::string> pipelines() const {
    std::lock_guard lock(mutex_);
    std::set<std::string> out;
    for (const auto& [prefix, pipeline] : live_) out.insert(pipeline);
    return out;
  }

 private:
  mutable std::mutex mutex_;
  std::map<eprosima::fastrtps::rtps::GuidPrefix_t, std::string> live_;
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
  void add(fdds::DataReader* reader, std::unique_ptr<TakeListener> listener) {
    std::lock_guard lock(readers_mutex_);
    readers_.push_back({reader, std::move(listener)});
  }
  /// For "every pipeline": a thread that adds a reader per newly seen pipeline.
  void watch(std::function<void()> poll) {
    watcher_ = std::thread([this, poll = std::move(poll)] {
      std::unique_lock lock(stop_mutex_);
      while (!stop_) {
        lock.unlock();
        poll();
        lock.lock();
        stop_changed_.wait_for(lock, std::chrono::milliseconds(200), [this] { return stop_; });
      }
    });
  }

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
  explicit ClientImpl(std::string name) : name_(std::move(name)) {
    // Wire ids unique across runs: a reply left in a transient-local history by an earlier
    // client with the same name can never be taken for ours.
    next_id_ = (static_cast<std::uint64_t>(Clock::now().time_since_epoch().count()) << 16) ^
               static_cast<std::uint64_t>(getpid());
  }

  ~ClientImpl() override {
    {
      std::lock_guard lock(replies_mutex_);
      closing_ = true;
    }
    if (info_gate_) {
      std::lock_guard lock(info_gate_->mutex);
      info_gate_->closed = true;
    }
    if (replies_gate_) {  // every command channel's reply listener
      std::lock_guard lock(replies_gate_->mutex);
      replies_gate_->closed = true;
    }
    delete_participant(participant_);
  }

  Status open(const ParticipantOptions& options) {
    auto created = create_participant(options, &participants_);
    if (!created) return created.status();
    participant_ = *created;
    if (Status s = detail::register_types(participant_); !s) return s;
    publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
    subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    if (publisher_ == nullptr || subscriber_ == nullptr) {
      return Status::error("dds client: could not create the DDS publisher/subscriber");
    }
    fdds::Topic* topic = find_or_create_topic(detail::kSignalsTopic, detail::type_name_signal_info());
    if (topic == nullptr) return Status::error("dds client: could not create topic lode/signals");
    info_gate_ = std::make_shared<Gate>();
    info_listener_ = std::make_unique<InfoListener>(
        info_gate_, [this](fdds::DataReader* r) { take_info(r); },
        [this](const fdds::InstanceHandle_t& writer) { forget_writer(writer); });
    info_reader_ = subscriber_->create_datareader(
        topic, detail::reader_qos(Durability::transient_local, 1, detail::kSignalInfoInstances),
        info_listener_.get(), fdds::StatusMask::data_available() << fdds::StatusMask::subscription_matched());
    if (info_reader_ == nullptr) return Status::error("dds client: could not create the reader of lode/signals");
    replies_gate_ = std::make_shared<Gate>();
    return Status::ok();
  }

  std::vector<SignalMeta> signals(std::chrono::milliseconds wait) override {
    std::unique_lock lock(signals_mutex_);
    signals_changed_.wait_for(lock, wait, [this] { return !signals_.empty(); });
    std::vector<SignalMeta> out;
    for (const auto& [topic, meta] : signals_) out.push_back(meta);
    return out;
  }

  std::vector<std::string> pipelines(std::chrono::milliseconds wait) override {
    // Each running pipeline's bridge is a participant named after it, and has one SignalInfo
    // writer. Either tells us it is live. Once something is heard, wait (within `wait`) until
    // every matched SignalInfo writer has delivered its pipeline's description: the first
    // pipeline heard of is not the only one live just because its data came first.
    const auto deadline = Clock::now() + wait;
    const auto heard = [this] {
      std::set<std::string> names = participants_.pipelines();
      std::lock_guard lock(signals_mutex_);
      for (const auto& [topic, meta] : signals_) names.insert(meta.pipeline);
      return names;
    };
    std::set<std::string> names = heard();
    while (Clock::now() < deadline) {
      if (!names.empty()) {
        fdds::SubscriptionMatchedStatus matched;
        std::size_t described = 0;
        {
          std::lock_guard lock(signals_mutex_);
          std::set<std::string> with_info;
          for (const auto& [topic, meta] : signals_) with_info.insert(meta.pipeline);
          described = with_info.size();
        }
        if (info_reader_->get_subscription_matched_status(matched) != ReturnCode_t::RETCODE_OK ||
            static_cast<std::size_t>(matched.current_count) <= described)
          break;
      }
      std::unique_lock lock(signals_mutex_);
      signals_changed_.wait_for(lock, std::chrono::milliseconds(50));
      lock.unlock();
      names = heard();
    }
    return {names.begin(), names.end()};
  }

  Expected<SignalMeta> resolve(const std::string& what, std::chrono::milliseconds wait) override {
    const auto deadline = Clock::now() + wait;
    std::unique_lock lock(signals_mutex_);
    while (true) {
      std::vector<SignalMeta> candidates = match(what);
      if (candidates.size() == 1) return candidates.front();
      if (candidates.size() > 1) {
        return Status::error("'" + what + "' is ambiguous: " + topic_list(candidates) +
                             " (give the pipeline, e.g. 'pipeline/block.port')");
      }
      if (signals_changed_.wait_until(lock, deadline) == std::cv_status::timeout) {
        candidates = match(what);
        if (candidates.size() == 1) return candidates.front();
        std::vector<SignalMeta> live;
        for (const auto& [topic, meta] : signals_) live.push_back(meta);
        return Status::error("no live signal matches '" + what + "' (waited " +
                             std::to_string(wait.count()) + " ms); live topics: " + topic_list(live));
      }
    }
  }

  Expected<std::unique_ptr<Subscription>> subscribe(
      const SignalMeta& meta, std::function<void(const SignalMeta&, const Sample&)> on_sample) override {
    const bool state = meta.kind == "state";
    fdds::Topic* topic = find_or_create_topic(
        meta.topic, state ? detail::type_name_stage_state() : detail::type_name_signal_sample());
    if (topic == nullptr) return Status::error("dds client: could not create topic '" + meta.topic + "'");
    auto gate = std::make_shared<Gate>();
    auto subscription = std::make_unique<ReaderSubscription>(*this, gate);
    TakeListener::Drain drain;
    if (!state) {
      drain = [meta, on_sample](fdds::DataReader* reader, Gate& g) {
        lode::msg::SignalSample s;
        fdds::SampleInfo info;
        Sample out;
        while (reader->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
          if (!info.valid_data) continue;
          out.received_ns = monotonic_ns();
          out.cycle = s.cycle();
          out.stamp_ns = s.stamp_ns();
          out.captured_ns = s.captured_ns();
          out.values = s.values();
          g.received.fetch_add(1, std::memory_order_relaxed);
          on_sample(meta, out);
        }
      };
    } else {
      drain = [meta, on_sample](fdds::DataReader* reader, Gate& g) {
        lode::msg::StageState s;
        fdds::SampleInfo info;
        Sample out;
        while (reader->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
          if (!info.valid_data) continue;
          out.received_ns = monotonic_ns();
          out.cycle = s.cycle();
          out.stamp_ns = s.stamp_ns();
          out.captured_ns = s.captured_ns();
          out.values = s.pose();
          out.values.insert(out.values.end(), s.twist().begin(), s.twist().end());
          out.values.insert(out.values.end(), s.covariance().begin(), s.covariance().end());
          g.received.fetch_add(1, std::memory_order_relaxed);
          on_sample(meta, out);
        }
      };
    }
    const std::int32_t depth = detail::one_second(meta.rate_hz, 64);
    if (Status s = add_reader(*subscription, topic,
                              detail::with_reliability(detail::reader_qos(Durability::volatile_, depth), meta.reliable),
                              gate, std::move(drain));
        !s) {
      return s;
    }
    return std::unique_ptr<Subscription>(std::move(subscription));
  }

  Expected<std::unique_ptr<Subscription>> subscribe_events(
      const std::string& pipeline, std::function<void(const EventSample&)> on_event) override {
    return subscribe_pipeline_topic(
        pipeline, "events", detail::type_name_event(),
        detail::reader_qos(Durability::transient_local, detail::kEventsDepth),
        [on_event](const std::string& p) -> TakeListener::Drain {
          return [on_event, p](fdds::DataReader* reader, Gate& g) {
            lode::msg::Event e;
            fdds::SampleInfo info;
            while (reader->take_next_sample(&e, &info) == ReturnCode_t::RETCODE_OK) {
              if (!info.valid_data) continue;
              g.received.fetch_add(1, std::memory_order_relaxed);
              on_event(EventSample{e.cycle(), e.stamp_ns(), p, e.kind(), e.text()});
            }
          };
        });
  }

  Expected<std::unique_ptr<Subscription>> subscribe_timing(
      const std::string& pipeline, std::function<void(const TimingSample&)> on_timing) override {
    return subscribe_pipeline_topic(
        pipeline, "timing", detail::type_name_timing(),
        detail::reader_qos(Durability::volatile_, detail::kTimingDepth),
        [on_timing](const std::string& p) -> TakeListener::Drain {
          return [on_timing, p](fdds::DataReader* reader, Gate& g) {
            lode::msg::TimingStats t;
            fdds::SampleInfo info;
            while (reader->take_next_sample(&t, &info) == ReturnCode_t::RETCODE_OK) {
              if (!info.valid_data) continue;
              TimingSample out;
              out.pipeline = p;
              out.cycle = t.cycle();
              out.executed = t.executed();
              out.overruns = t.overruns();
              out.missed_periods = t.missed_periods();
              out.telemetry_dropped = t.telemetry_dropped();
              out.rate_hz = t.rate_hz();
              out.wake_latency = row_from(t.wake_latency());
              out.cycle_time = row_from(t.cycle_time());
              for (const auto& b : t.blocks()) out.blocks.push_back(row_from(b));
              g.received.fetch_add(1, std::memory_order_relaxed);
              on_timing(out);
            }
          };
        });
  }

  Expected<ControlReply> command(const std::string& pipeline, ControlRequest request,
                                 std::chrono::milliseconds timeout) override {
    const auto deadline = Clock::now() + timeout;
    const std::string no_reply = "no reply within " + std::to_string(timeout.count()) +
                                 " ms: is the pipeline running with telemetry.commands.enabled?";
    auto channel = command_channel(pipeline);
    if (!channel) return channel.status();
    // Wait until the pipeline's command reader and reply writer are matched: a command
    // written before that would reach nobody (volatile).
    const auto matched = [&] {
      fdds::PublicationMatchedStatus pub;
      fdds::SubscriptionMatchedStatus sub;
      return (*channel)->writer->get_publication_matched_status(pub) == ReturnCode_t::RETCODE_OK &&
             (*channel)->reader->get_subscription_matched_status(sub) == ReturnCode_t::RETCODE_OK &&
             pub.current_count > 0 && sub.current_count > 0;
    };
    while (!matched()) {
      if (Clock::now() >= deadline) {
        return Status::error(no_reply + " (no command reader on " + pipeline_topic(pipeline, "command") +
                             " was found)");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }

    lode::msg::Command c;
    std::uint64_t wire_id = 0;
    {
      std::lock_guard lock(replies_mutex_);
      wire_id = ++next_id_;
    }
    c.client(name_);
    c.id(wire_id);
    c.kind(request.kind);
    c.block(request.block);
    c.name(request.name);
    c.value(request.value);
    c.plugin(request.plugin);
    if (!(*channel)->writer->write(&c)) {
      return Status::error("could not send the command to " + pipeline_topic(pipeline, "command"));
    }
    std::unique_lock lock(replies_mutex_);
    while (true) {
      auto it = std::find_if(replies_.begin(), replies_.end(),
                             [&](const lode::msg::Reply& r) { return r.id() == wire_id; });
      if (it != replies_.end()) {
        ControlReply reply;
        reply.id = request.id;
        reply.ok = it->ok();
        reply.message = it->message();
        reply.value = it->value();
        replies_.erase(it);
        return reply;
      }
      if (replies_changed_.wait_until(lock, deadline) == std::cv_status::timeout) {
        const bool arrived = std::any_of(replies_.begin(), replies_.end(),
                                         [&](const lode::msg::Reply& r) { return r.id() == wire_id; });
        if (!arrived) return Status::error(no_reply);
      }
    }
  }

  fdds::Topic* find_or_create_topic(const std::string& name, const char* type) {
    std::lock_guard lock(topics_mutex_);
    if (auto* existing = participant_->lookup_topicdescription(name)) {
      return dynamic_cast<fdds::Topic*>(existing);
    }
    return participant_->create_topic(name, type, fdds::TOPIC_QOS_DEFAULT);
  }

  void delete_reader(fdds::DataReader* reader) { subscriber_->delete_datareader(reader); }

 private:
  Status add_reader(ReaderSubscription& subscription, fdds::Topic* topic, const fdds::DataReaderQos& qos,
                    std::shared_ptr<Gate> gate, TakeListener::Drain drain) {
    auto listener = std::make_unique<TakeListener>(std::move(gate), std::move(drain));
    fdds::DataReader* reader =
        subscriber_->create_datareader(topic, qos, listener.get(), fdds::StatusMask::data_available());
    if (reader == nullptr) {
      return Status::error("dds client: could not create a reader on '" + topic->get_name() + "'");
    }
    subscription.add(reader, std::move(listener));
    return Status::ok();
  }

  using DrainFor = std::function<TakeListener::Drain(const std::string& pipeline)>;

  /// lode/<p>/<what> of one pipeline, or of every pipeline as its SignalInfo appears.
  Expected<std::unique_ptr<Subscription>> subscribe_pipeline_topic(const std::string& pipeline,
                                                                   const std::string& what, const char* type,
                                                                   const fdds::DataReaderQos& qos,
                                                                   DrainFor drain_for) {
    auto gate = std::make_shared<Gate>();
    auto subscription = std::make_unique<ReaderSubscription>(*this, gate);
    const auto add = [this, what, type, qos, gate, drain_for](ReaderSubscription& s,
                                                              const std::string& p) -> Status {
      const std::string name = pipeline_topic(p, what);
      fdds::Topic* topic = find_or_create_topic(name, type);
      if (topic == nullptr) return Status::error("dds client: could not create topic '" + name + "'");
      return add_reader(s, topic, qos, gate, drain_for(p));
    };
    if (!pipeline.empty()) {
      if (Status s = add(*subscription, pipeline); !s) return s;
    } else {
      ReaderSubscription* raw = subscription.get();
      auto seen = std::make_shared<std::set<std::string>>();
      raw->watch([this, raw, seen, add] {
        for (const auto& p : pipelines(std::chrono::milliseconds(0))) {
          if (seen->insert(p).second) (void)add(*raw, p);
        }
      });
    }
    return std::unique_ptr<Subscription>(std::move(subscription));
  }

  Expected<CommandChannel*> command_channel(const std::string& pipeline) {
    std::lock_guard lock(commands_mutex_);
    if (auto it = commands_.find(pipeline); it != commands_.end()) return &it->second;
    const std::string command_name = pipeline_topic(pipeline, "command");
    const std::string reply_name = pipeline_topic(pipeline, "reply");
    fdds::Topic* command_topic = find_or_create_topic(command_name, detail::type_name_command());
    fdds::Topic* reply_topic = find_or_create_topic(reply_name, detail::type_name_reply());
    if (command_topic == nullptr || reply_topic == nullptr) {
      return Status::error("dds client: could not create topics " + command_name + " / " + reply_name);
    }
    CommandChannel channel;
    channel.listener = std::make_unique<TakeListener>(replies_gate_, [this](fdds::DataReader* r, Gate&) {
      lode::msg::Reply reply;
      fdds::SampleInfo info;
      while (r->take_next_sample(&reply, &info) == ReturnCode_t::RETCODE_OK) {
        if (!info.valid_data || reply.client() != name_) continue;
        std::lock_guard replies_lock(replies_mutex_);
        if (closing_) return;
        replies_.push_back(reply);
        if (replies_.size() > 256) replies_.pop_front();  // never collected: its command timed out
        replies_changed_.notify_all();
      }
    });
    channel.reader = subscriber_->create_datareader(
        reply_topic, detail::reader_qos(Durability::transient_local, detail::kReplyDepth),
        channel.listener.get(), fdds::StatusMask::data_available());
    channel.writer = publisher_->create_datawriter(
        command_topic, detail::keep_all_commands(detail::writer_qos(Durability::volatile_, 1), 2.0));
    if (channel.reader == nullptr || channel.writer == nullptr) {
      return Status::error("dds client: could not create the command writer / reply reader of '" +
                           pipeline + "'");
    }
    return &commands_.emplace(pipeline, std::move(channel)).first->second;
  }

  void take_info(fdds::DataReader* reader) {
    lode::msg::SignalInfo info;
    fdds::SampleInfo sample_info;
    while (reader->take_next_sample(&info, &sample_info) == ReturnCode_t::RETCODE_OK) {
      std::lock_guard lock(signals_mutex_);
      if (sample_info.valid_data) {
        handles_[sample_info.instance_handle] = info.topic();
        writers_[info.topic()] = sample_info.publication_handle;
        signals_[info.topic()] = meta_from(info);
      } else if (sample_info.instance_state != fdds::ALIVE_INSTANCE_STATE) {
        // The pipeline is gone (its writer left or disposed the topic).
        if (auto it = handles_.find(sample_info.instance_handle); it != handles_.end()) {
          signals_.erase(it->second);
          writers_.erase(it->second);
          handles_.erase(it);
        }
      }
      signals_changed_.notify_all();
    }
  }

  /// A SignalInfo writer unmatched (its pipeline stopped without disposing, or its
  /// participant's lease expired): its topics are no longer live.
  void forget_writer(const fdds::InstanceHandle_t& writer) {
    std::lock_guard lock(signals_mutex_);
    for (auto it = writers_.begin(); it != writers_.end();) {
      if (it->second == writer) {
        signals_.erase(it->first);
        it = writers_.erase(it);
      } else {
        ++it;
      }
    }
    signals_changed_.notify_all();
  }

  /// Forms: "lode/p/b/port", "p/b/port", "p/b.port", "b.port", "p/state", "state".
  std::vector<SignalMeta> match(const std::string& what) const {
    std::vector<SignalMeta> out;
    std::string pipeline, rest = what;
    if (what.rfind("lode/", 0) == 0) {
      if (auto it = signals_.find(what); it != signals_.end()) out.push_back(it->second);
      return out;
    }
    if (auto slash = what.find('/'); slash != std::string::npos) {
      pipeline = what.substr(0, slash);
      rest = what.substr(slash + 1);
    }
    std::string block, port;
    if (auto slash = rest.find('/'); slash != std::string::npos) {
      block = rest.substr(0, slash);
      port = rest.substr(slash + 1);
    } else if (auto dot = rest.rfind('.'); dot != std::string::npos) {
      block = rest.substr(0, dot);
      port = rest.substr(dot + 1);
    }
    for (const auto& [topic, meta] : signals_) {
      if (!pipeline.empty() && meta.pipeline != pipeline) continue;
      const bool hit = block.empty() ? (rest == "state" && meta.kind == "state")
                                     : (meta.kind == "signal" && meta.block == block && meta.port == port);
      if (hit) out.push_back(meta);
    }
    return out;
  }

  std::string name_;
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

ReaderSubscription::~ReaderSubscription() {
  {
    std::lock_guard lock(stop_mutex_);
    stop_ = true;
  }
  stop_changed_.notify_all();
  if (watcher_.joinable()) watcher_.join();
  {
    std::lock_guard lock(gate_->mutex);  // waits for a callback in progress
    gate_->closed = true;
  }
  std::lock_guard lock(readers_mutex_);
  for (auto& entry : readers_) client_.delete_reader(entry.reader);
}

}  // namespace

Expected<std::unique_ptr<Client>> Client::create(const ParticipantOptions& options) {
  ParticipantOptions named = options;
  if (named.name.empty()) named.name = options_from_environment("").name;
  auto client = std::make_unique<ClientImpl>(named.name);
  if (Status s = client->open(named); !s) return s;
  return std::unique_ptr<Client>(std::move(client));
}

}  // namespace lode::dds
