// The telemetry bridge and the client in one process: a real pipeline (source.sine) run by
// the Scheduler on a simulated clock, its TelemetryTap and ControlService as hooks, the
// bridge publishing over the loopback transport (shared memory + UDPv4 127.0.0.1, no
// multicast) and a Client subscribing and commanding, each test on a private DDS domain.
#include <gtest/gtest.h>
#include <pthread.h>

#include <filesystem>
#include <fstream>
#include <sys/resource.h>
#include <sched.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iostream>
#include <mutex>
#include <numbers>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>

#include "lode/sdk/tunables.hpp"
#include "lode/control.hpp"
#include "lode/dds/bridge.hpp"
#include "lode/dds/client.hpp"
#include "lode/dds/participant.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "lode/telemetry.hpp"
#include "lode/testing/private_domain.hpp"
#include "common.hpp"  // the QoS the bridge and the client use
#include "lode_msgs.h"

namespace {

using namespace std::chrono_literals;
namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::types::ReturnCode_t;
using lode::dds::Client;
using lode::dds::ParticipantOptions;
using lode::dds::TelemetryBridge;

constexpr double kAmplitudeX = 1.0e-3;
constexpr double kFrequencyX = 5.0;

std::string pipeline_yaml(int domain, const std::string& extra_telemetry) {
  return "pipeline: ddsdemo\n"
         "rate_hz: 1000\n"
         "blocks:\n"
         "  wobble:\n"
         "    plugin: source.sine\n"
         "    names: [x, theta_z]\n"
         "    units: [m, rad]\n"
         "    amplitude: [1.0e-3, 0.5]\n"
         "    frequency_hz: [5, 2]\n"
         "telemetry:\n"
         "  domain: " + std::to_string(domain) + "\n"
         "  transport: loopback\n"
         "  rate_hz: 1000\n"
         "  timing_rate_hz: 20\n"
         "  publish: [wobble.out]\n" + extra_telemetry;
}

/// A pipeline with its telemetry hooks and a running bridge.
struct Rig {
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  std::unique_ptr<lode::Pipeline> pipeline;
  lode::EventLog events;
  lode::SimulatedClock clock;
  std::unique_ptr<lode::Scheduler> scheduler;
  std::unique_ptr<lode::TelemetryTap> tap;
  std::unique_ptr<lode::ControlService> control;
  std::unique_ptr<TelemetryBridge> bridge;  // last: stopped first

  explicit Rig(const std::string& yaml, bool start_bridge = true) {
    pipeline = lode::Pipeline::load_text(yaml, "dds_bridge_test.yaml", registry, diag);
    if (!pipeline) {
      ADD_FAILURE() << diag.format();
      return;
    }
    const auto activated = pipeline->activate();
    if (!activated) {
      ADD_FAILURE() << activated.message();
      return;
    }
    const lode::TelemetrySpec& spec = pipeline->telemetry();
    scheduler = std::make_unique<lode::Scheduler>(*pipeline, clock, events);
    tap = std::make_unique<lode::TelemetryTap>(spec, pipeline->rate_hz());
    control = std::make_unique<lode::ControlService>(*pipeline, events);
    scheduler->add_hook(control.get());
    scheduler->add_hook(tap.get());
    if (!start_bridge) return;
    ParticipantOptions options;
    options.domain = spec.domain;
    options.name = "ddsdemo-stage";
    options.transport = spec.transport;
    auto started = TelemetryBridge::start(*pipeline, spec, *tap, scheduler->stats(), events,
                                          spec.commands.enabled ? control.get() : nullptr, options);
    if (!started) {
      ADD_FAILURE() << started.error();
      return;
    }
    bridge = std::move(*started);
  }
  ~Rig() {
    if (bridge) bridge->stop();
    if (pipeline) pipeline->deactivate();
  }
  [[nodiscard]] bool ok() const { return bridge != nullptr; }
  [[nodiscard]] bool loaded() const { return scheduler != nullptr; }

  double tunable(const std::string& block, const std::string& name) const {
    auto* b = dynamic_cast<lode::Tunables*>(pipeline->block(block));
    if (b == nullptr) {
      ADD_FAILURE() << block << " has no runtime parameters";
      return 0.0;
    }
    const auto list = b->tunables();
    for (std::size_t i = 0; i < list.size(); ++i)
      if (list[i].name == name) return b->tunable_value(i);
    ADD_FAILURE() << "no tunable " << block << "." << name;
    return NAN;
  }
  bool has_event(const std::string& kind, const std::string& text_part) const {
    for (const auto& e : events.snapshot())
      if (e.kind == kind && e.text.find(text_part) != std::string::npos) return true;
    return false;
  }
};

std::unique_ptr<Client> make_client(int domain, const std::string& name) {
  ParticipantOptions options;
  options.domain = domain;
  options.name = name;
  auto client = Client::create(options);
  if (!client) {
    ADD_FAILURE() << client.error();
    return nullptr;
  }
  return std::move(*client);
}

/// A pipeline with its bridge running (`extra_telemetry` appended to its telemetry: section)
/// and a client named `client_name`, on a DDS domain of their own.
struct PipelineAndClient {
  const int domain = lode::testing::private_dds_domain();
  Rig rig;
  std::unique_ptr<Client> client;  // after the rig: destroyed before its bridge stops

  PipelineAndClient(const std::string& extra_telemetry, const std::string& client_name)
      : rig(pipeline_yaml(domain, extra_telemetry)) {
    if (rig.ok()) client = make_client(domain, client_name);
  }
  /// Both are up (each reports its own failure).
  [[nodiscard]] bool ok() const { return rig.ok() && client != nullptr; }
};

template <typename Predicate>
bool wait_for(Predicate done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

lode::ControlRequest request(const std::string& kind, const std::string& block, const std::string& name,
                             const std::string& value = "") {
  lode::ControlRequest r;
  r.kind = kind;
  r.block = block;
  r.name = name;
  r.value = value;
  return r;
}

// --- transports: errors name the field, nothing is created -------------------------------

TEST(Participant, InvalidAddressesNameTheField) {
  eprosima::fastdds::dds::DomainParticipantQos qos;
  ParticipantOptions options;
  options.name = "x";
  options.transport.kind = lode::TransportSpec::Kind::network;
  options.transport.interfaces = {"127.0.0.1", "eth0"};
  auto s = lode::dds::configure_participant_qos(options, qos);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("telemetry.network.interfaces[1]: 'eth0'"), std::string::npos) << s.message();

  options.transport.interfaces = {"127.0.0.1"};
  options.transport.initial_peers = {"10.0.0.2:7412", "10.0.0.300"};
  s = lode::dds::configure_participant_qos(options, qos);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("telemetry.network.initial_peers[1]: '10.0.0.300'"), std::string::npos) << s.message();

  options.transport.initial_peers = {"10.0.0.2:99999"};
  s = lode::dds::configure_participant_qos(options, qos);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("invalid port"), std::string::npos) << s.message();

  options.transport.initial_peers = {"10.0.0.2:7412"};
  options.transport.multicast = false;
  EXPECT_TRUE(lode::dds::configure_participant_qos(options, qos));
  EXPECT_FALSE(qos.transport().use_builtin_transports);
  EXPECT_EQ(qos.transport().user_transports.size(), 2u);  // UDPv4 on the NIC + shared memory
  EXPECT_EQ(qos.wire_protocol().builtin.initialPeersList.size(), 1u);
  EXPECT_EQ(qos.wire_protocol().builtin.metatrafficUnicastLocatorList.size(), 1u);  // no multicast

  options.domain = 300;
  s = lode::dds::configure_participant_qos(options, qos);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("telemetry.domain"), std::string::npos) << s.message();
}

TEST(Participant, TheHighestDomainIdStartsOnEveryTransport) {
  // Domain 232 is the last the RTPS port mapping allows, with room for participants 0..62
  // only: the loopback transport's unicast discovery must not name ports past 65535 (Fast DDS
  // then refuses the participant with "Calculated port number is too high"). Nothing is sent
  // to anyone: no test takes domains above 229 (private_domain.hpp).
  namespace fdds = eprosima::fastdds::dds;
  for (const auto kind : {lode::TransportSpec::Kind::loopback, lode::TransportSpec::Kind::udp_loopback,
                          lode::TransportSpec::Kind::shm}) {
    fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
    ParticipantOptions options;
    options.name = "highest-domain";
    options.domain = 232;
    options.transport.kind = kind;
    ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
    auto* factory = fdds::DomainParticipantFactory::get_instance();
    fdds::DomainParticipant* participant = factory->create_participant(232, qos);
    EXPECT_NE(participant, nullptr) << "transport " << lode::to_string(kind);
    if (participant) factory->delete_participant(participant);
  }
}

TEST(Participant, LoopbackIsHermetic) {
  eprosima::fastdds::dds::DomainParticipantQos qos;
  ParticipantOptions options;
  options.name = "x";
  ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
  EXPECT_EQ(qos.name().to_string(), "x");
  EXPECT_FALSE(qos.transport().use_builtin_transports);
  EXPECT_EQ(qos.transport().user_transports.size(), 2u);  // shared memory + UDPv4 127.0.0.1
  // Unicast discovery on 127.0.0.1: no SPDP multicast on any interface.
  ASSERT_EQ(qos.wire_protocol().builtin.metatrafficUnicastLocatorList.size(), 1u);
  EXPECT_EQ(qos.wire_protocol().builtin.metatrafficMulticastLocatorList.size(), 0u);
}

/// The shared-memory transports a participant's QoS configures.
std::vector<std::shared_ptr<eprosima::fastdds::rtps::SharedMemTransportDescriptor>> shared_memory_transports(
    const eprosima::fastdds::dds::DomainParticipantQos& qos) {
  std::vector<std::shared_ptr<eprosima::fastdds::rtps::SharedMemTransportDescriptor>> found;
  for (const auto& transport : qos.transport().user_transports)
    if (auto shm = std::dynamic_pointer_cast<eprosima::fastdds::rtps::SharedMemTransportDescriptor>(transport))
      found.push_back(std::move(shm));
  return found;
}

TEST(Participant, SharedMemoryHoldsASecondOfABusyPipeline) {
  // A best-effort sample is lost when the reader's port queue or the writer's segment is
  // full; Fast DDS's defaults (512 descriptors, 512 KiB) are 90 ms of 7 topics at 800 Hz,
  // and `lode record` lost samples on a loaded host with them.
  eprosima::fastdds::dds::DomainParticipantQos qos;
  ParticipantOptions options;
  options.name = "x";
  for (const auto kind : {lode::TransportSpec::Kind::loopback, lode::TransportSpec::Kind::shm,
                          lode::TransportSpec::Kind::network}) {
    options.transport.kind = kind;
    ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
    const auto shared_memory = shared_memory_transports(qos);
    for (const auto& shm : shared_memory) {
      EXPECT_GE(shm->port_queue_capacity(), 7u * 800u) << lode::to_string(kind) << ": port queue (descriptors)";
      EXPECT_GE(shm->segment_size(), 4u << 20) << lode::to_string(kind) << ": segment (bytes)";
    }
    EXPECT_EQ(shared_memory.size(), 1u) << lode::to_string(kind);
  }
}

TEST(Participant, SharedMemoryPortsAreFoundAliveWithinAShortSleep) {
  // A process opening another's port whose health check fails sleeps a third of the port's
  // health-check timeout before checking again, on its event thread: with Fast DDS's
  // 1000 ms, 2 or 3 in 20 `lode echo` sent their first ACKNACK 333 ms late.
  eprosima::fastdds::dds::DomainParticipantQos qos;
  ParticipantOptions options;
  options.name = "x";
  for (const auto kind : {lode::TransportSpec::Kind::loopback, lode::TransportSpec::Kind::shm,
                          lode::TransportSpec::Kind::network}) {
    options.transport.kind = kind;
    ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
    for (const auto& shm : shared_memory_transports(qos))
      EXPECT_LE(shm->healthy_check_timeout_ms() / 3, 50u) << lode::to_string(kind) << ": retry after (ms)";
  }
}

TEST(Participant, UdpReceiveBuffersHoldBurstsOfSamples) {
  // Samples reach a reader on this host as UDP datagrams too; the kernel's default receive
  // buffer (208 KiB) overflowed when `lode record` did not run for tens of milliseconds.
  eprosima::fastdds::dds::DomainParticipantQos qos;
  ParticipantOptions options;
  options.name = "x";
  for (const auto kind : {lode::TransportSpec::Kind::loopback, lode::TransportSpec::Kind::udp_loopback,
                          lode::TransportSpec::Kind::network}) {
    options.transport.kind = kind;
    ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
    int udp = 0;
    for (const auto& transport : qos.transport().user_transports) {
      const auto descriptor =
          std::dynamic_pointer_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor>(transport);
      if (!descriptor) continue;
      ++udp;
      EXPECT_GE(descriptor->receiveBufferSize, 4u << 20) << lode::to_string(kind);
    }
    EXPECT_EQ(udp, 1) << lode::to_string(kind);
  }
}

TEST(Participant, ReliableWritersHeartbeatOftenEnoughForLateJoiners) {
  // A late joiner that matches a reliable writer after the writer sent it the history and
  // its first HEARTBEAT gets the data at the next HEARTBEAT: with Fast DDS's 3 s, `lode echo`
  // sometimes waited 3 s for the metadata and `--duration 3` printed nothing.
  using lode::dds::detail::Durability;
  for (const auto durability : {Durability::transient_local, Durability::volatile_}) {
    const auto qos = lode::dds::detail::writer_qos(durability, 10);
    const auto& period = qos.reliable_writer_qos().times.heartbeatPeriod;
    EXPECT_LE(period.to_ns(), 100'000'000) << "heartbeat period " << period.seconds << " s " << period.nanosec << " ns";
  }
}

TEST(Participant, OptionsFromEnvironment) {
  setenv("LODE_DDS_DOMAIN", "177", 1);
  setenv("LODE_DDS_TRANSPORT", "network", 1);
  setenv("LODE_DDS_PEERS", "10.0.0.2, 10.0.0.3:7412", 1);
  setenv("LODE_DDS_INTERFACES", "10.0.0.1", 1);
  const auto o = lode::dds::options_from_environment("");
  unsetenv("LODE_DDS_DOMAIN");
  unsetenv("LODE_DDS_TRANSPORT");
  unsetenv("LODE_DDS_PEERS");
  unsetenv("LODE_DDS_INTERFACES");
  EXPECT_EQ(o.domain, 177);
  EXPECT_EQ(o.transport.kind, lode::TransportSpec::Kind::network);
  EXPECT_EQ(o.transport.initial_peers, (std::vector<std::string>{"10.0.0.2", "10.0.0.3:7412"}));
  EXPECT_EQ(o.transport.interfaces, (std::vector<std::string>{"10.0.0.1"}));
  EXPECT_EQ(o.name.rfind("lode-", 0), 0u) << o.name;
  EXPECT_NE(o.name.find('@'), std::string::npos) << o.name;
}

// --- data ---------------------------------------------------------------------------------

TEST(Bridge, EverySampleArrivesInOrderWithMetadata) {
  constexpr std::uint64_t kCycles = 10000;
  PipelineAndClient session("  history: 2048\n", "lode-test-client");
  ASSERT_TRUE(session.ok());
  Rig& rig = session.rig;
  auto& client = session.client;

  auto meta = client->resolve("wobble.out", 10s);
  ASSERT_TRUE(meta) << meta.error();
  EXPECT_EQ(meta->topic, "lode/ddsdemo/wobble/out");
  EXPECT_EQ(meta->pipeline, "ddsdemo");
  EXPECT_EQ(meta->kind, "signal");
  EXPECT_EQ(meta->names, (std::vector<std::string>{"x", "theta_z"}));
  EXPECT_EQ(meta->units, (std::vector<std::string>{"m", "rad"}));
  EXPECT_DOUBLE_EQ(meta->rate_hz, 1000.0);
  EXPECT_EQ(meta->decimation, 1u);
  // Every accepted spelling resolves to the same topic.
  for (const char* what : {"ddsdemo/wobble.out", "lode/ddsdemo/wobble/out", "ddsdemo/wobble/out"}) {
    auto m = client->resolve(what, 1s);
    ASSERT_TRUE(m) << what << ": " << m.error();
    EXPECT_EQ(m->topic, meta->topic);
  }
  auto missing = client->resolve("wobble.nope", 200ms);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("live topics: lode/ddsdemo/wobble/out"), std::string::npos) << missing.error();

  std::mutex mutex;
  std::vector<lode::dds::Sample> samples;
  samples.reserve(kCycles);
  auto sub = client->subscribe(*meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample& s) {
    std::lock_guard lock(mutex);
    samples.push_back(s);
  });
  ASSERT_TRUE(sub) << sub.error();
  ASSERT_TRUE(wait_for([&] { return rig.bridge->matched_readers() >= 1; }, 10s)) << "the reader never matched";

  // Simulated time runs ~100x faster than real time; pace it at the scheduler's idle calls
  // (every 1024 cycles) so the test checks delivery, not the ring's capacity.
  std::atomic<bool> stop{false};
  const auto on_idle = [&] {
    rig.bridge->flush();
    const auto published = rig.bridge->stats().published;
    (void)wait_for([&] { return (*sub)->received() >= published; }, 5s);
  };
  const auto t0 = std::chrono::steady_clock::now();
  const auto result = rig.scheduler->run(kCycles, stop, on_idle);
  ASSERT_FALSE(result.faulted) << result.fault;
  rig.bridge->flush();
  ASSERT_TRUE(wait_for([&] { return (*sub)->received() >= kCycles; }, 20s))
      << "received " << (*sub)->received() << " of " << kCycles;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::lock_guard lock(mutex);
  ASSERT_EQ(samples.size(), kCycles);
  std::vector<double> latency_us;
  for (std::uint64_t k = 0; k < kCycles; ++k) {
    const auto& s = samples[k];
    ASSERT_EQ(s.cycle, k) << "gap or reordering at sample " << k;
    ASSERT_EQ(s.stamp_ns, static_cast<std::int64_t>(k) * 1'000'000);
    ASSERT_EQ(s.values.size(), 2u);
    const double t = static_cast<double>(k) / 1000.0;
    EXPECT_NEAR(s.values[0], kAmplitudeX * std::sin(2 * std::numbers::pi * kFrequencyX * t), 1e-12);
    EXPECT_LE(s.captured_ns, s.received_ns);
    latency_us.push_back(static_cast<double>(s.received_ns - s.captured_ns) / 1000.0);
  }
  EXPECT_EQ(rig.tap->dropped(), 0u);
  EXPECT_EQ(rig.bridge->stats().ring_dropped, 0u);
  EXPECT_EQ(rig.bridge->stats().published, kCycles);
  std::cout << "[ measured ] " << kCycles << " samples in " << wall_s << " s = "
            << static_cast<double>(kCycles) / wall_s << " samples/s (burst, simulated clock); "
            << "capture->callback latency p50 " << percentile(latency_us, 0.5) << " us, p99 "
            << percentile(latency_us, 0.99) << " us, max " << percentile(latency_us, 1.0) << " us\n";
}

TEST(Bridge, LateJoinerGetsMetadataEventsAndTiming) {
  const int kDomain = lode::testing::private_dds_domain();
  Rig rig(pipeline_yaml(kDomain, ""));
  ASSERT_TRUE(rig.ok());
  rig.events.post(0, 0, "start", "ddsdemo started (test)");
  rig.bridge->flush();
  std::this_thread::sleep_for(300ms);  // SignalInfo and the event are long written

  auto client = make_client(kDomain, "late-joiner");
  ASSERT_TRUE(client);
  const auto signals = client->signals(10s);
  ASSERT_EQ(signals.size(), 1u);
  EXPECT_EQ(signals[0].topic, "lode/ddsdemo/wobble/out");
  EXPECT_EQ(signals[0].names, (std::vector<std::string>{"x", "theta_z"}));
  EXPECT_EQ(client->pipelines(0ms), (std::vector<std::string>{"ddsdemo"}));

  // Events are transient-local: the late joiner sees the one posted before it existed,
  // both subscribed to this pipeline and to every pipeline.
  std::mutex mutex;
  std::vector<lode::dds::EventSample> one, all;
  auto events_one = client->subscribe_events("ddsdemo", [&](const lode::dds::EventSample& e) {
    std::lock_guard lock(mutex);
    one.push_back(e);
  });
  auto events_all = client->subscribe_events("", [&](const lode::dds::EventSample& e) {
    std::lock_guard lock(mutex);
    all.push_back(e);
  });
  ASSERT_TRUE(events_one && events_all);
  std::vector<lode::dds::TimingSample> timing;
  auto timing_sub = client->subscribe_timing("ddsdemo", [&](const lode::dds::TimingSample& t) {
    std::lock_guard lock(mutex);
    timing.push_back(t);
  });
  ASSERT_TRUE(timing_sub);
  std::atomic<bool> stop{false};
  ASSERT_FALSE(rig.scheduler->run(2000, stop, nullptr).faulted);
  EXPECT_TRUE(wait_for([&] { return (*events_one)->received() >= 1 && (*events_all)->received() >= 1; }, 10s));
  EXPECT_TRUE(wait_for([&] {
    std::lock_guard lock(mutex);
    return !timing.empty() && timing.back().executed == 2000;
  }, 10s));
  {
    // Released before the bridge stops: its listeners (Fast DDS threads) take this mutex while
    // Fast DDS holds its own locks, which stop() needs.
    std::lock_guard lock(mutex);
    ASSERT_FALSE(one.empty());
    EXPECT_EQ(one[0].pipeline, "ddsdemo");
    EXPECT_EQ(one[0].kind, "start");
    EXPECT_EQ(one[0].text, "ddsdemo started (test)");
    ASSERT_FALSE(all.empty());
    EXPECT_EQ(all[0].text, "ddsdemo started (test)");
    ASSERT_FALSE(timing.empty());
    const auto& t = timing.back();
    EXPECT_EQ(t.pipeline, "ddsdemo");
    EXPECT_DOUBLE_EQ(t.rate_hz, 1000.0);
    ASSERT_FALSE(t.blocks.empty());
    EXPECT_EQ(t.blocks[0].name, "wobble");
    EXPECT_EQ(t.blocks[0].count, 2000u);
  }

  // A pipeline that stops takes its signals with it.
  rig.bridge->stop();
  EXPECT_TRUE(wait_for([&] { return client->signals(0ms).empty(); }, 10s))
      << "signals of a stopped pipeline are still listed";
}

TEST(Bridge, StalledReaderNeverBlocksTheScheduler) {
  const int kDomain = lode::testing::private_dds_domain();
  constexpr std::uint64_t kCycles = 20000;
  Rig rig(pipeline_yaml(kDomain, ""));
  ASSERT_TRUE(rig.ok());
  // Paced like a real run, ~5 ms of real time per 1024 cycles: the publisher keeps up.
  const auto paced = [] { std::this_thread::sleep_for(5ms); };
  std::atomic<bool> stop{false};

  auto baseline = rig.scheduler->run(kCycles, stop, paced);
  rig.bridge->flush();
  // Normally 0; a machine loaded by other jobs can starve the publisher for a moment.
  const auto dropped_before = rig.bridge->stats().ring_dropped;

  auto client = make_client(kDomain, "stalled-reader");
  ASSERT_TRUE(client);
  auto meta = client->resolve("wobble.out", 10s);
  ASSERT_TRUE(meta) << meta.error();
  std::atomic<bool> stall{true};
  std::atomic<bool> reported{false};
  auto sub = client->subscribe(*meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample&) {
    if (!reported.exchange(true)) {
      char name[32] = {};
      pthread_getname_np(pthread_self(), name, sizeof name);
      std::cout << "[ info ] stalled callback runs on thread '" << name << "'\n";
    }
    while (stall.load()) std::this_thread::sleep_for(1ms);  // a reader that never keeps up
  });
  ASSERT_TRUE(sub);
  ASSERT_TRUE(wait_for([&] { return rig.bridge->matched_readers() >= 1; }, 10s));

  auto stalled = rig.scheduler->run(kCycles, stop, paced);
  const auto after = rig.bridge->stats();
  stall = false;
  sub->reset();  // waits for the callback, deletes the reader
  std::cout << "[ measured ] " << kCycles << " cycles: " << baseline.wall_s << " s without a reader, "
            << stalled.wall_s << " s with a stalled reader; ring drops " << dropped_before << " then "
            << after.ring_dropped
            << ", published " << after.published << "\n";
  // A blocked scheduler would take hours (one sample per stalled callback); allow noise.
  EXPECT_LT(stalled.wall_s, baseline.wall_s + 2.0);
  // The stalled in-process callback holds the publisher thread (intra-process delivery):
  // nearly every record of the second run is dropped, and counted.
  EXPECT_GT(after.ring_dropped - dropped_before, kCycles / 2) << "the stall should have been counted as drops";
  EXPECT_EQ(after.ring_dropped, rig.tap->dropped());  // no write() failed: KEEP_LAST never blocks
}

TEST(Bridge, RealClockLatency) {
  const int kDomain = lode::testing::private_dds_domain();
  constexpr std::uint64_t kCycles = 3000;
  // Same pipeline on the wall clock: one sample per millisecond, as in `lode run`.
  Rig rig(pipeline_yaml(kDomain, ""), /*start_bridge=*/false);  // only its pipeline is used
  ASSERT_TRUE(rig.loaded());
  lode::RealClock clock;
  lode::Scheduler scheduler(*rig.pipeline, clock, rig.events);
  lode::TelemetryTap tap(rig.pipeline->telemetry(), rig.pipeline->rate_hz());
  scheduler.add_hook(&tap);
  ParticipantOptions options;
  options.domain = kDomain;
  options.name = "ddsdemo-realtime";
  auto bridge = TelemetryBridge::start(*rig.pipeline, rig.pipeline->telemetry(), tap, scheduler.stats(),
                                       rig.events, nullptr, options);
  ASSERT_TRUE(bridge) << bridge.error();
  auto client = make_client(kDomain, "latency-probe");
  ASSERT_TRUE(client);
  auto meta = client->resolve("wobble.out", 10s);
  ASSERT_TRUE(meta) << meta.error();
  std::mutex mutex;
  std::vector<double> latency_us;
  std::uint64_t last_cycle = 0, out_of_order = 0;
  latency_us.reserve(kCycles);
  auto sub = client->subscribe(*meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample& s) {
    std::lock_guard lock(mutex);
    // Gaps are periods the scheduler skipped (overrun policy skip); going back is a fault.
    if (!latency_us.empty() && s.cycle <= last_cycle) ++out_of_order;
    last_cycle = s.cycle;
    latency_us.push_back(static_cast<double>(s.received_ns - s.captured_ns) / 1000.0);
  });
  ASSERT_TRUE(sub);
  ASSERT_TRUE(wait_for([&] { return (*bridge)->matched_readers() >= 1; }, 10s));
  std::atomic<bool> stop{false};
  const auto result = scheduler.run(kCycles, stop, nullptr);
  ASSERT_FALSE(result.faulted) << result.fault;
  (*bridge)->flush();
  const std::uint64_t executed = scheduler.stats().executed.load();
  EXPECT_GT(executed, kCycles / 2);
  EXPECT_TRUE(wait_for([&] { return (*sub)->received() >= executed; }, 10s)) << (*sub)->received();
  const auto bridge_stats = (*bridge)->stats();
  (*bridge)->stop();
  std::lock_guard lock(mutex);
  EXPECT_EQ(bridge_stats.published, executed);
  EXPECT_EQ(bridge_stats.ring_dropped, 0u);
  EXPECT_EQ(latency_us.size(), executed);
  EXPECT_EQ(out_of_order, 0u);
  EXPECT_EQ(tap.dropped(), 0u);
  std::cout << "[ measured ] real clock 1 kHz, " << latency_us.size() << " samples (" << kCycles - executed
            << " periods skipped by the scheduler) in " << result.wall_s
            << " s: capture->callback latency p50 " << percentile(latency_us, 0.5) << " us, p90 "
            << percentile(latency_us, 0.9) << " us, p99 " << percentile(latency_us, 0.99) << " us, max "
            << percentile(latency_us, 1.0) << " us; the RT thread woke the publisher with a system call in "
            << tap.doorbell().wakes() << " of " << tap.doorbell().sequence() << " cycles\n";
  // Loose: the VM has two noisy vCPUs.
  EXPECT_LT(percentile(latency_us, 0.5), 20000.0);
}

// A real-time loop's publisher is SCHED_FIFO below the RT thread by default, at most 10; a
// loop with normal scheduling keeps a normally scheduled publisher.
TEST(Bridge, ThePublishersPriorityFollowsTheLoops) {
  const auto publisher_priority = [](const std::string& realtime) {
    std::string yaml = pipeline_yaml(1, "");
    yaml.replace(yaml.find("rate_hz: 1000\n"), 14, "rate_hz: 1000\n" + realtime);
    lode::PluginRegistry registry;
    lode::Diagnostics diag;
    auto p = lode::Pipeline::load_text(yaml, "priority.yaml", registry, diag);
    EXPECT_TRUE(p) << diag.format();
    return p ? p->telemetry().publisher_priority : -1;
  };
  EXPECT_EQ(publisher_priority(""), 0);
  EXPECT_EQ(publisher_priority("realtime: {priority: 80}\n"), lode::kDefaultPublisherPriority);
  EXPECT_EQ(publisher_priority("realtime: {priority: 5}\n"), 4);
  EXPECT_EQ(publisher_priority("realtime: {priority: 1}\n"), 0);
}

/// The scheduling policy and priority of this process's thread named `name` (-1, -1: none).
std::pair<int, int> thread_scheduling(const std::string& name) {
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string text;
    std::getline(comm, text);
    if (text != name) continue;
    const pid_t tid = static_cast<pid_t>(std::stol(task.path().filename().string()));
    sched_param sp{};
    if (sched_getparam(tid, &sp) != 0) return {-1, -1};
    return {sched_getscheduler(tid), sp.sched_priority};
  }
  return {-1, -1};
}

TEST(Bridge, ThePublisherRunsAtItsPriorityOrSaysWhyNot) {
  const int kDomain = lode::testing::private_dds_domain();
  Rig rig(pipeline_yaml(kDomain, "  priority: 7\n"));
  ASSERT_TRUE(rig.ok());
  std::pair<int, int> scheduling{-1, -1};
  ASSERT_TRUE(wait_for([&] {
    scheduling = thread_scheduling("lode-telemetry");
    return scheduling.first >= 0;
  }, 5s)) << "no thread lode-telemetry";
  rlimit rtprio{};
  getrlimit(RLIMIT_RTPRIO, &rtprio);
  const bool allowed = geteuid() == 0 || rtprio.rlim_cur >= 7;
  // The priority is set as the thread starts: give it the moment.
  wait_for([&] { return (scheduling = thread_scheduling("lode-telemetry")).first == SCHED_FIFO || !allowed; }, 5s);
  if (allowed) {
    EXPECT_EQ(scheduling.first, SCHED_FIFO);
    EXPECT_EQ(scheduling.second, 7);
    EXPECT_EQ(rig.bridge->stats().publisher_priority, 7) << "the run's summary would not say so";
  } else {
    EXPECT_EQ(scheduling.first, SCHED_OTHER);
    EXPECT_EQ(rig.bridge->stats().publisher_priority, 0);
    bool warned = false;
    ASSERT_TRUE(wait_for([&] {
      for (const auto& e : rig.events.snapshot())
        warned = warned || (e.kind == "warning" && e.text.find("telemetry.priority 7: SCHED_FIFO refused") != std::string::npos);
      return warned;
    }, 5s)) << "no warning that the priority was refused";
  }
}

TEST(Bridge, TheDoorbellWakesThePublisherLongBeforeItsPollingPeriod) {
  // publish_period_ms at its maximum, 100 ms: a publisher that only polled (here every 50 ms,
  // for the timing topic at 20 Hz) would deliver a sample 25 ms after its capture in the
  // median. Woken by the RT thread's doorbell it delivers within a fraction of a millisecond
  // on an idle host, but this test runs beside others on two CPUs (a QEMU guest, a browser)
  // and its publisher is an ordinary thread: one such run measured a median of 5.1 ms. Half
  // of polling's median still tells the two apart.
  const int kDomain = lode::testing::private_dds_domain();
  constexpr std::uint64_t kCycles = 1500;
  Rig rig(pipeline_yaml(kDomain, "  publish_period_ms: 100\n"), /*start_bridge=*/false);
  ASSERT_TRUE(rig.loaded());
  ASSERT_DOUBLE_EQ(rig.pipeline->telemetry().publish_period_s, 0.1);
  lode::RealClock clock;
  lode::Scheduler scheduler(*rig.pipeline, clock, rig.events);
  lode::TelemetryTap tap(rig.pipeline->telemetry(), rig.pipeline->rate_hz());
  scheduler.add_hook(&tap);
  ParticipantOptions options;
  options.domain = kDomain;
  options.name = "ddsdemo-doorbell";
  auto bridge = TelemetryBridge::start(*rig.pipeline, rig.pipeline->telemetry(), tap, scheduler.stats(),
                                       rig.events, nullptr, options);
  ASSERT_TRUE(bridge) << bridge.error();
  auto client = make_client(kDomain, "doorbell-probe");
  ASSERT_TRUE(client);
  auto meta = client->resolve("wobble.out", 10s);
  ASSERT_TRUE(meta) << meta.error();
  std::mutex mutex;
  std::vector<double> latency_us;
  latency_us.reserve(kCycles);
  auto sub = client->subscribe(*meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample& s) {
    std::lock_guard lock(mutex);
    latency_us.push_back(static_cast<double>(s.received_ns - s.captured_ns) / 1000.0);
  });
  ASSERT_TRUE(sub);
  ASSERT_TRUE(wait_for([&] { return (*bridge)->matched_readers() >= 1; }, 10s));
  std::atomic<bool> stop{false};
  const auto result = scheduler.run(kCycles, stop, nullptr);
  ASSERT_FALSE(result.faulted) << result.fault;
  const std::uint64_t executed = scheduler.stats().executed.load();
  EXPECT_TRUE(wait_for([&] { return (*sub)->received() >= executed; }, 10s)) << (*sub)->received();
  (*bridge)->stop();
  std::lock_guard lock(mutex);
  ASSERT_GT(latency_us.size(), kCycles / 2);
  std::cout << "[ measured ] publish_period_ms 100: capture->callback latency p50 " << percentile(latency_us, 0.5)
            << " us, p99 " << percentile(latency_us, 0.99) << " us; " << tap.doorbell().sequence()
            << " rings, " << tap.doorbell().wakes() << " with a system call\n";
  EXPECT_LT(percentile(latency_us, 0.5), 12500.0) << "the publisher waited for its polling period: the doorbell did not wake it";
  EXPECT_EQ(tap.doorbell().sequence(), executed) << "one ring per cycle that published";
}

TEST(Bridge, StateTopicCarriesPoseAndCovariance) {
  const int kDomain = lode::testing::private_dds_domain();
  std::string yaml = pipeline_yaml(kDomain, "  state: {pose: wobble.out, covariance: spread.out, rate_hz: 100}\n");
  yaml.replace(yaml.find("telemetry:"), 0,
               "  spread:\n"
               "    plugin: source.sine\n"
               "    names: [xx, xt, tx, tt]\n"
               "    units: [m^2, m*rad, m*rad, rad^2]\n"
               "    offset: [1, 2, 3, 4]\n"
               "    amplitude: [0, 0, 0, 0]\n"
               "    frequency_hz: [0, 0, 0, 0]\n");
  Rig rig(yaml);
  ASSERT_TRUE(rig.ok());
  auto client = make_client(kDomain, "state-reader");
  ASSERT_TRUE(client);
  for (const char* what : {"state", "ddsdemo/state"}) {
    auto m = client->resolve(what, 10s);
    ASSERT_TRUE(m) << what << ": " << m.error();
    EXPECT_EQ(m->topic, "lode/ddsdemo/state");
  }
  auto meta = client->resolve("state", 1s);
  ASSERT_TRUE(meta);
  EXPECT_EQ(meta->kind, "state");
  EXPECT_EQ(meta->pose_size, 2u);
  EXPECT_EQ(meta->twist_size, 0u);
  EXPECT_EQ(meta->covariance_size, 4u);
  EXPECT_DOUBLE_EQ(meta->rate_hz, 100.0);
  EXPECT_EQ(meta->decimation, 10u);
  EXPECT_EQ(meta->names, (std::vector<std::string>{"x", "theta_z", "xx", "xt", "tx", "tt"}));
  std::mutex mutex;
  std::vector<lode::dds::Sample> samples;
  auto sub = client->subscribe(*meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample& s) {
    std::lock_guard lock(mutex);
    samples.push_back(s);
  });
  ASSERT_TRUE(sub);
  ASSERT_TRUE(wait_for([&] { return rig.bridge->matched_readers() >= 1; }, 10s));
  std::atomic<bool> stop{false};
  ASSERT_FALSE(rig.scheduler->run(1000, stop, nullptr).faulted);
  rig.bridge->flush();
  ASSERT_TRUE(wait_for([&] { return (*sub)->received() >= 100; }, 10s)) << (*sub)->received();
  std::lock_guard lock(mutex);
  ASSERT_EQ(samples.size(), 100u);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].cycle, 10 * i);
    ASSERT_EQ(samples[i].values.size(), 6u);
    EXPECT_EQ(std::vector<double>(samples[i].values.begin() + 2, samples[i].values.end()),
              (std::vector<double>{1, 2, 3, 4}));
  }
}

// --- commands -----------------------------------------------------------------------------

TEST(Commands, SetGetAndPreciseErrors) {
  PipelineAndClient session("  commands: {enabled: true}\n", "console");
  ASSERT_TRUE(session.ok());
  Rig& rig = session.rig;
  auto& client = session.client;

  auto reply = client->command("ddsdemo", request("set", "wobble", "amplitude.x", "0.002"), 10s);
  ASSERT_TRUE(reply) << reply.error();
  EXPECT_TRUE(reply->ok) << reply->message;
  EXPECT_EQ(reply->value, "0.002");
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), 0.002);
  EXPECT_TRUE(rig.has_event("parameter", "amplitude.x")) << "no parameter event";
  EXPECT_TRUE(rig.has_event("parameter", "(by console)"));

  constexpr int kGets = 20;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < kGets; ++i) {
    reply = client->command("ddsdemo", request("get", "wobble", "amplitude.x"), 5s);
    ASSERT_TRUE(reply) << reply.error();
    EXPECT_TRUE(reply->ok);
    EXPECT_EQ(reply->value, "0.002");
  }
  std::cout << "[ measured ] command round trip (get, pipeline not running): "
            << std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / kGets
            << " us mean over " << kGets << "\n";

  struct Bad {
    lode::ControlRequest r;
    const char* message;
  };
  const std::vector<Bad> bad = {
      {request("set", "wobble", "frequency_hz.x", "1e6"), "is outside"},
      {request("set", "nope", "amplitude.x", "1"), "no block 'nope'"},
      {request("set", "wobble", "gain", "1"), "has no runtime parameter 'gain'"},
      {request("set", "wobble", "amplitude.x", "0.3abc"), "'0.3abc' is not a number"},
      {request("launch", "wobble", "amplitude.x", "1"), "unknown command kind 'launch'"},
  };
  for (const auto& b : bad) {
    auto r = client->command("ddsdemo", b.r, 5s);
    ASSERT_TRUE(r) << r.error();
    EXPECT_FALSE(r->ok) << b.r.kind << " " << b.r.block << "." << b.r.name << " = " << b.r.value;
    EXPECT_NE(r->message.find(b.message), std::string::npos) << "expected '" << b.message << "' in: " << r->message;
  }
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), 0.002);
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "frequency_hz.x"), kFrequencyX);

  // While the scheduler runs, the change is applied by the RT thread at a cycle boundary.
  std::atomic<bool> stop{false};
  rig.control->set_running(true);
  lode::Expected<lode::ControlReply> running_reply = lode::Status::error("not sent");
  std::thread commander([&] {
    running_reply = client->command("ddsdemo", request("set", "wobble", "amplitude.theta_z", "0.25"), 10s);
    stop = true;
  });
  const auto result = rig.scheduler->run(0, stop, [] { std::this_thread::sleep_for(1ms); });
  commander.join();
  rig.control->set_running(false);
  EXPECT_TRUE(result.stopped_by_request);
  ASSERT_TRUE(running_reply) << running_reply.error();
  EXPECT_TRUE(running_reply->ok) << running_reply->message;
  EXPECT_NE(running_reply->message.find("at cycle"), std::string::npos) << running_reply->message;
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.theta_z"), 0.25);

  const auto stats = rig.bridge->stats();
  EXPECT_EQ(stats.commands_accepted, 2u + kGets + 5u);
  EXPECT_EQ(stats.commands_refused, 0u);
}

TEST(Commands, RefusedParticipantIsAnsweredCountedAndLogged) {
  PipelineAndClient session("  commands: {enabled: true, allow_participants: [console]}\n", "intruder");
  ASSERT_TRUE(session.ok());
  Rig& rig = session.rig;
  auto& intruder = session.client;
  auto reply = intruder->command("ddsdemo", request("set", "wobble", "amplitude.x", "5"), 10s);
  ASSERT_TRUE(reply) << reply.error();
  EXPECT_FALSE(reply->ok);
  EXPECT_NE(reply->message.find("refused: participant 'intruder' from hosts ["), std::string::npos) << reply->message;
  EXPECT_NE(reply->message.find("(see telemetry.commands.allow_participants)"), std::string::npos) << reply->message;
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), kAmplitudeX);
  EXPECT_TRUE(rig.has_event("command_refused", "participant 'intruder'"));
  EXPECT_FALSE(rig.has_event("parameter", "amplitude.x"));

  auto console = make_client(session.domain, "console");
  ASSERT_TRUE(console);
  reply = console->command("ddsdemo", request("set", "wobble", "amplitude.x", "0.004"), 10s);
  ASSERT_TRUE(reply) << reply.error();
  EXPECT_TRUE(reply->ok) << reply->message;
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), 0.004);
  EXPECT_EQ(rig.bridge->stats().commands_refused, 1u);
  EXPECT_EQ(rig.bridge->stats().commands_accepted, 1u);
}

TEST(Commands, RefusedHost) {
  PipelineAndClient session("  commands: {enabled: true, allow_hosts: [10.255.255.1]}\n", "console");
  ASSERT_TRUE(session.ok());
  Rig& rig = session.rig;
  auto& client = session.client;
  auto reply = client->command("ddsdemo", request("set", "wobble", "amplitude.x", "5"), 10s);
  ASSERT_TRUE(reply) << reply.error();
  EXPECT_FALSE(reply->ok);
  EXPECT_NE(reply->message.find("refused: participant 'console' from hosts [127.0.0.1"), std::string::npos)
      << reply->message;
  EXPECT_NE(reply->message.find("(see telemetry.commands.allow_hosts)"), std::string::npos) << reply->message;
  EXPECT_TRUE(rig.has_event("command_refused", "allow_hosts"));
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), kAmplitudeX);
}

TEST(Commands, LoopbackHostAllowed) {
  PipelineAndClient session("  commands: {enabled: true, allow_hosts: [127.0.0.1], allow_participants: [console]}\n",
                            "console");
  ASSERT_TRUE(session.ok());
  Rig& rig = session.rig;
  auto& client = session.client;
  auto reply = client->command("ddsdemo", request("set", "wobble", "amplitude.x", "0.003"), 10s);
  ASSERT_TRUE(reply) << reply.error();
  EXPECT_TRUE(reply->ok) << reply->message;
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), 0.003);
}

TEST(Commands, ABurstOfAThousandIsAnsweredOrPushedBackNeverLost) {
  // A console that writes 1000 commands back to back, as fast as Fast DDS takes them. Each
  // must either be answered (a reply with its id) or refused to the sender by write() (the
  // reader is full and the writer's blocking time ran out): none may vanish. With a
  // KEEP_LAST 32 reader, 118 of 1000 used to get neither.
  const int kDomain = lode::testing::private_dds_domain();
  Rig rig(pipeline_yaml(kDomain, "  commands: {enabled: true}\n"));
  ASSERT_TRUE(rig.ok());
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  ParticipantOptions options;
  options.domain = kDomain;
  options.name = "burst-console";
  options.transport.kind = lode::TransportSpec::Kind::loopback;
  ASSERT_TRUE(lode::dds::configure_participant_qos(options, qos));
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipant* participant = factory->create_participant(static_cast<fdds::DomainId_t>(kDomain), qos);
  ASSERT_NE(participant, nullptr);
  struct Cleanup {
    fdds::DomainParticipant* p;
    ~Cleanup() {
      p->delete_contained_entities();
      fdds::DomainParticipantFactory::get_instance()->delete_participant(p);
    }
  } cleanup{participant};
  ASSERT_TRUE(lode::dds::detail::register_types(participant));
  fdds::Topic* command_topic = participant->create_topic("lode/ddsdemo/command", lode::dds::detail::type_name_command(),
                                                         fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* reply_topic = participant->create_topic("lode/ddsdemo/reply", lode::dds::detail::type_name_reply(),
                                                       fdds::TOPIC_QOS_DEFAULT);
  ASSERT_TRUE(command_topic && reply_topic);
  using lode::dds::detail::Durability;
  fdds::DataWriter* writer = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT)->create_datawriter(
      command_topic, lode::dds::detail::keep_all_commands(lode::dds::detail::writer_qos(Durability::volatile_, 1), 2.0));
  fdds::DataReaderQos reply_qos = lode::dds::detail::reader_qos(Durability::transient_local, 1);
  reply_qos = lode::dds::detail::keep_all_commands(reply_qos, 0.0);
  reply_qos.resource_limits().max_samples = reply_qos.resource_limits().max_samples_per_instance = 4096;
  fdds::DataReader* reader = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT)->create_datareader(
      reply_topic, reply_qos);
  ASSERT_TRUE(writer && reader);
  ASSERT_TRUE(wait_for([&] {
    fdds::PublicationMatchedStatus w;
    fdds::SubscriptionMatchedStatus r;
    return writer->get_publication_matched_status(w) == ReturnCode_t::RETCODE_OK && w.current_count >= 1 &&
           reader->get_subscription_matched_status(r) == ReturnCode_t::RETCODE_OK && r.current_count >= 1;
  }, 10s));

  // Both sides matched as this console sees them does not mean the pipeline has matched the
  // console's reply reader: each participant learns of the other's endpoints on its own
  // schedule. Replies written before that reach this reader only from the writer's
  // transient-local history, whose last 256 cannot hold a burst of 1000 (4 of 30 loaded runs
  // got exactly those 256). A console that has had one answer knows the way back is open.
  constexpr std::uint64_t kProbeId = 1'000'000;
  {
    lode::msg::Command probe;
    probe.client("burst-console");
    probe.id(kProbeId);
    probe.kind("status");
    ASSERT_TRUE(writer->write(&probe));
    ASSERT_TRUE(wait_for([&] {
      lode::msg::Reply r;
      fdds::SampleInfo info;
      while (reader->take_next_sample(&r, &info) == ReturnCode_t::RETCODE_OK) {
        if (info.valid_data && r.client() == "burst-console" && r.id() == kProbeId) return true;
      }
      return false;
    }, 10s)) << "the probe command was never answered";
  }

  constexpr std::uint64_t kCommands = 1000;
  std::set<std::uint64_t> refused_at_write;
  const auto start = std::chrono::steady_clock::now();
  for (std::uint64_t id = 1; id <= kCommands; ++id) {
    lode::msg::Command c;
    c.client("burst-console");
    c.id(id);
    c.kind("set");
    c.block("wobble");
    c.name("amplitude.x");
    c.value(std::to_string(1.0e-3 + static_cast<double>(id) * 1e-9));
    if (!writer->write(&c)) refused_at_write.insert(id);
  }
  std::set<std::uint64_t> answered;
  std::size_t ok_replies = 0;
  std::string first_refusal;
  wait_for([&] {
    lode::msg::Reply r;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&r, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data || r.client() != "burst-console") continue;
      answered.insert(r.id());
      if (r.ok()) ++ok_replies;
      else if (first_refusal.empty()) first_refusal = r.message();
    }
    return answered.size() + refused_at_write.size() >= kCommands;
  }, 60s);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::size_t lost = 0;
  for (std::uint64_t id = 1; id <= kCommands; ++id) lost += !answered.count(id) && !refused_at_write.count(id);
  std::cout << "[ measured ] " << kCommands << " commands: " << answered.size() << " answered (" << ok_replies
            << " ok), " << refused_at_write.size() << " refused to the sender by write(), " << lost << " lost, in "
            << seconds << " s\n";
  EXPECT_EQ(lost, 0u);
  EXPECT_EQ(ok_replies, answered.size()) << "a valid set was refused: " << first_refusal;
  // The last value written is the one in force: the burst was applied in order.
  EXPECT_DOUBLE_EQ(rig.tunable("wobble", "amplitude.x"), 1.0e-3 + static_cast<double>(kCommands) * 1e-9);
}

TEST(Commands, NoPipelineTimesOutWithAHint) {
  auto client = make_client(177, "console");
  ASSERT_TRUE(client);
  auto reply = client->command("absent", request("status", "", ""), 300ms);
  ASSERT_FALSE(reply);
  EXPECT_NE(reply.error().find("no reply within 300 ms: is the pipeline running with telemetry.commands.enabled?"),
            std::string::npos)
      << reply.error();
}

}  // namespace
