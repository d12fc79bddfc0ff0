// Subscriptions: the samples of one signal or state topic, and the events or timing of one
// pipeline or of every pipeline. Each hands what it takes to the caller's callback on the
// reader's listener thread, under the subscription's gate.
//
// Events/timing of "every pipeline" (empty name): a thread of the subscription looks at
// the pipelines known from `lode/signals` every 200 ms and adds a reader for each new one;
// a pipeline that publishes no signal and no state has no SignalInfo and is not found.
#include "client_impl.hpp"
#include "local_delivery.hpp"
#include "lode/sdk/clock.hpp"

namespace lode::dds::client_detail {

namespace {

using OnSample = std::function<void(const SignalMeta&, const Sample&)>;

/// FNV-1a of the writer's GUID: which writer sent a sample, in the 8 bytes Sample has for it.
std::uint64_t writer_hash(const eprosima::fastrtps::rtps::GUID_t& guid) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  const auto mix = [&h](const auto& bytes) {
    for (const auto byte : bytes) h = (h ^ static_cast<std::uint8_t>(byte)) * 0x100000001b3ULL;
  };
  mix(guid.guidPrefix.value);
  mix(guid.entityId.value);
  return h;
}

/// The drain of a signal or state topic, `Message` being SignalSample or StageState: the
/// two differ only in where the values come from (`values_of`).
template <typename Message, typename ValuesOf>
TakeListener::Drain sample_drain(const SignalMeta& meta, const OnSample& on_sample, ValuesOf values_of) {
  return [meta, on_sample, values_of](fdds::DataReader* reader, Gate& g) {
    Sample out;
    take_valid<Message>(reader, [&](const Message& s, const fdds::SampleInfo& info) {
      out.received_ns = monotonic_ns();
      out.writer = writer_hash(info.sample_identity.writer_guid());
      out.sequence = static_cast<std::uint64_t>(info.sample_identity.sequence_number().to64long());
      out.cycle = s.cycle();
      out.stamp_ns = s.stamp_ns();
      out.captured_ns = s.captured_ns();
      values_of(s, out.values);
      g.received.fetch_add(1, std::memory_order_relaxed);
      on_sample(meta, out);
    });
  };
}

TimingSample::Row row_from(const lode::msg::LatencySummary& s) {
  return {s.name(), s.count(), s.p50_us(), s.p90_us(), s.p99_us(), s.p999_us(), s.max_us(), s.mean_us()};
}

TimingSample timing_from(const lode::msg::TimingStats& t, const std::string& pipeline) {
  TimingSample out;
  out.pipeline = pipeline;
  out.cycle = t.cycle();
  out.executed = t.executed();
  out.overruns = t.overruns();
  out.missed_periods = t.missed_periods();
  out.telemetry_dropped = t.telemetry_dropped();
  out.rate_hz = t.rate_hz();
  out.wake_latency = row_from(t.wake_latency());
  out.cycle_time = row_from(t.cycle_time());
  for (const auto& b : t.blocks()) out.blocks.push_back(row_from(b));
  return out;
}

}  // namespace

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

void ReaderSubscription::add(fdds::DataReader* reader, std::unique_ptr<TakeListener> listener) {
  std::lock_guard lock(readers_mutex_);
  readers_.push_back({reader, std::move(listener)});
}

void ReaderSubscription::retire_readers() {
  std::lock_guard gate(gate_->mutex);  // waits for a callback in progress
  std::lock_guard lock(readers_mutex_);
  for (auto& entry : readers_) entry.listener->retire();
}

void ReaderSubscription::watch(std::function<void()> poll) {
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

Expected<std::unique_ptr<Subscription>> ClientImpl::subscribe(const SignalMeta& meta, OnSample on_sample) {
  const bool state = meta.kind == "state";
  fdds::Topic* topic = find_or_create_topic(
      meta.topic, state ? detail::type_name_stage_state() : detail::type_name_signal_sample());
  if (topic == nullptr) return Status::error("dds client: could not create topic '" + meta.topic + "'");
  auto gate = std::make_shared<Gate>();
  auto subscription = std::make_unique<ReaderSubscription>(*this, gate);
  TakeListener::Drain drain =
      !state ? sample_drain<lode::msg::SignalSample>(
                   meta, on_sample,
                   [](const lode::msg::SignalSample& s, std::vector<double>& values) { values = s.values(); })
             : sample_drain<lode::msg::StageState>(
                   meta, on_sample, [](const lode::msg::StageState& s, std::vector<double>& values) {
                     values = s.pose();
                     values.insert(values.end(), s.twist().begin(), s.twist().end());
                     values.insert(values.end(), s.covariance().begin(), s.covariance().end());
                   });
  const std::int32_t depth = detail::one_second(meta.rate_hz, 64);
  const fdds::DataReaderQos qos =
      detail::with_reliability(detail::reader_qos(Durability::volatile_, depth), meta.reliable);
  // Shared memory alone where the pipeline can deliver through it (local_delivery.hpp):
  // otherwise every sample comes twice, once as a datagram on 127.0.0.1.
  std::optional<eprosima::fastrtps::rtps::Locator_t> shared_memory;
  const auto own = participant_->guid().guidPrefix;
  if (transport_ == TransportSpec::Kind::loopback && participants_.shared_memory_reaches_us(meta.pipeline, own)) {
    std::lock_guard lock(shared_memory_mutex_);
    if (!shared_memory_tried_) shared_memory_port_ = detail::SharedMemoryPort::claim(*participant_);
    shared_memory_tried_ = true;
    if (shared_memory_port_) shared_memory = shared_memory_port_->locator();
  }
  if (!shared_memory) {
    if (Status s = add_reader(*subscription, topic, qos, gate, std::move(drain)); !s) return s;
    return std::unique_ptr<Subscription>(std::move(subscription));
  }
  fdds::DataReaderQos local = qos;
  local.endpoint().unicast_locator_list.push_back(*shared_memory);
  if (Status s = add_reader(*subscription, topic, local, gate, drain); !s) return s;
  // A pipeline of that name that cannot deliver through shared memory (restarted by another
  // user, say) would never reach that reader: from then on the subscription reads over UDP,
  // through a second reader, the first one retired.
  ReaderSubscription* raw = subscription.get();
  subscription->watch([this, raw, topic, qos, gate, drain, own, pipeline = meta.pipeline, fell_back = false]() mutable {
    if (fell_back || participants_.count(pipeline) == 0 || participants_.shared_memory_reaches_us(pipeline, own)) return;
    raw->retire_readers();
    fell_back = add_reader(*raw, topic, qos, gate, drain).is_ok();
  });
  return std::unique_ptr<Subscription>(std::move(subscription));
}

Expected<std::unique_ptr<Subscription>> ClientImpl::subscribe_events(
    const std::string& pipeline, std::function<void(const EventSample&)> on_event) {
  return subscribe_pipeline_topic(
      pipeline, "events", detail::type_name_event(),
      detail::reader_qos(Durability::transient_local, detail::kEventsDepth),
      [on_event](const std::string& p) -> TakeListener::Drain {
        return [on_event, p](fdds::DataReader* reader, Gate& g) {
          take_valid<lode::msg::Event>(reader, [&](const lode::msg::Event& e) {
            g.received.fetch_add(1, std::memory_order_relaxed);
            on_event(EventSample{e.cycle(), e.stamp_ns(), p, e.kind(), e.text()});
          });
        };
      });
}

Expected<std::unique_ptr<Subscription>> ClientImpl::subscribe_timing(
    const std::string& pipeline, std::function<void(const TimingSample&)> on_timing) {
  return subscribe_pipeline_topic(
      pipeline, "timing", detail::type_name_timing(),
      detail::reader_qos(Durability::volatile_, detail::kTimingDepth),
      [on_timing](const std::string& p) -> TakeListener::Drain {
        return [on_timing, p](fdds::DataReader* reader, Gate& g) {
          take_valid<lode::msg::TimingStats>(reader, [&](const lode::msg::TimingStats& t) {
            const TimingSample out = timing_from(t, p);
            g.received.fetch_add(1, std::memory_order_relaxed);
            on_timing(out);
          });
        };
      });
}

Status ClientImpl::add_reader(ReaderSubscription& subscription, fdds::Topic* topic, const fdds::DataReaderQos& qos,
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

Expected<std::unique_ptr<Subscription>> ClientImpl::subscribe_pipeline_topic(const std::string& pipeline,
                                                                             const std::string& what,
                                                                             const char* type,
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

}  // namespace lode::dds::client_detail
