// DDS Security with the lab PKI of tools/dds-security/make-lab-certs.sh, on raw Fast DDS 2.9
// participants made by lode::dds::configure_participant_qos with transport udp_loopback (UDPv4
// on 127.0.0.1, unicast discovery): who can discover whom and who may command.
//
// Identities (see tools/dds-security/README.md): `stage` publishes lode/* and subscribes
// lode/*/command; `console` publishes lode/*/command and subscribes everything; `observer`
// subscribes everything and may not publish lode/*/command. Topic types are the lode IDL's
// (lode::msg::Command, Reply, SignalSample). Each test on a private DDS domain.
#include "security.hpp"

#include <gtest/gtest.h>

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include "lode/sdk/testing/require.hpp"

#include "lode/dds/participant.hpp"
#include "lode/testing/private_domain.hpp"
#include "lode_msgs.h"
#include "lode_msgsPubSubTypes.h"


namespace {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// One "pipeline" name per process: another build running this test at the same time (same
// domains) then shares discovery with us but never a topic.
const std::string kPipeline = "lab" + std::to_string(::getpid());
const std::string kCommandTopic = "lode/" + kPipeline + "/command";
const std::string kReplyTopic = "lode/" + kPipeline + "/reply";
const std::string kTelemetryTopic = "lode/" + kPipeline + "/xy/position";
// Generous: two shared, noisy cores and an ECDH + ECDSA handshake per pair of participants.
constexpr auto kMatchTimeout = 30s;
// How long a refused participant gets to (not) match once a permitted one already has.
constexpr auto kRefusalWindow = 3s;

template <typename Predicate>
bool wait_until(Predicate predicate, Clock::duration timeout) {
  const auto deadline = Clock::now() + timeout;
  while (!predicate()) {
    if (Clock::now() > deadline) {
      return false;
    }
    std::this_thread::sleep_for(10ms);
  }
  return true;
}

int matched(fdds::DataWriter* writer) {
  fdds::PublicationMatchedStatus status;
  writer->get_publication_matched_status(status);
  return status.current_count;
}

int matched(fdds::DataReader* reader) {
  fdds::SubscriptionMatchedStatus status;
  reader->get_subscription_matched_status(status);
  return status.current_count;
}

// Takes everything the reader holds; returns the valid samples.
template <typename T>
std::vector<T> take_all(fdds::DataReader* reader) {
  std::vector<T> samples;
  T sample;
  fdds::SampleInfo info;
  while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) {
      samples.push_back(sample);
    }
  }
  return samples;
}

lode::msg::Command make_command(const std::string& client, std::uint64_t id) {
  lode::msg::Command command;
  command.client(client);
  command.id(id);
  command.kind("status");
  return command;
}

// What this participant learnt about others: SPDP discovery (by name) and the outcome of
// the DDS Security handshake (by GUID, mapped back to the name discovery gave).
class DiscoveryLog final : public fdds::DomainParticipantListener {
 public:
  void on_participant_discovery(fdds::DomainParticipant* /*participant*/,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override {
    using Info = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
    std::lock_guard lock(mutex_);
    const std::string name = info.info.m_participantName.to_string();
    names_[guid_text(info.info.m_guid)] = name;
    const char* what = info.status == Info::DISCOVERED_PARTICIPANT  ? "discovered"
                       : info.status == Info::CHANGED_QOS_PARTICIPANT ? "changed"
                       : info.status == Info::REMOVED_PARTICIPANT     ? "removed"
                       : info.status == Info::DROPPED_PARTICIPANT     ? "dropped"
                                                                      : "ignored";
    events_.push_back(std::string(what) + " " + name);
  }
  void onParticipantAuthentication(fdds::DomainParticipant* /*participant*/,
                                   eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) override {
    using Info = eprosima::fastrtps::rtps::ParticipantAuthenticationInfo;
    std::lock_guard lock(mutex_);
    const auto known = names_.find(guid_text(info.guid));
    const std::string name = known != names_.end() ? known->second : "<" + guid_text(info.guid) + ">";
    events_.push_back((info.status == Info::AUTHORIZED_PARTICIPANT ? "authorized " : "unauthorized ") + name);
  }
  bool saw(const std::string& event) const {
    std::lock_guard lock(mutex_);
    return std::find(events_.begin(), events_.end(), event) != events_.end();
  }
  std::string events() const {
    std::lock_guard lock(mutex_);
    std::string text;
    for (const auto& event : events_) text += (text.empty() ? "" : ", ") + event;
    return text;
  }

 private:
  static std::string guid_text(const eprosima::fastrtps::rtps::GUID_t& guid) {
    std::ostringstream text;
    text << guid;
    return text.str();
  }
  mutable std::mutex mutex_;
  std::map<std::string, std::string> names_;  // GUID -> participant name
  std::vector<std::string> events_;
};

// One participant with the lode types registered and lazily created topics; deletes
// everything it created.
class Node {
 public:
  Node(int domain, int participant_id, std::string name, lode::SecuritySpec security)
      : domain_(domain), participant_id_(participant_id), name_(std::move(name)), security_(std::move(security)) {}
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;
  ~Node() {
    if (participant_ != nullptr) {
      participant_->delete_contained_entities();
      fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
    }
  }

  // Empty on success, else why the participant could not be created.
  std::string start() {
    fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
    lode::dds::ParticipantOptions options;
    options.domain = domain_;
    options.name = name_;
    options.transport.kind = lode::TransportSpec::Kind::udp_loopback;
    options.security = security_;
    if (lode::Status status = lode::dds::configure_participant_qos(options, qos); !status) {
      return status.message();
    }
    // Fast DDS 2.9 gives every participant of a process a new id, and unicast discovery on
    // 127.0.0.1 only reaches ids below the initial-peers range: fixed ids keep this test
    // (which creates and deletes dozens of participants) inside it.
    qos.wire_protocol().participant_id = participant_id_;
    participant_ = fdds::DomainParticipantFactory::get_instance()->create_participant(
        static_cast<fdds::DomainId_t>(domain_), qos, &discovery_);
    if (participant_ == nullptr) {
      return "Fast DDS refused to create participant " + name_ + " (see its log above)";
    }
    fdds::TypeSupport(new lode::msg::CommandPubSubType()).register_type(participant_);
    fdds::TypeSupport(new lode::msg::ReplyPubSubType()).register_type(participant_);
    fdds::TypeSupport(new lode::msg::SignalSamplePubSubType()).register_type(participant_);
    publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
    subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    if (publisher_ == nullptr || subscriber_ == nullptr) {
      return "cannot create publisher/subscriber of " + name_;
    }
    return {};
  }

  // nullptr when access control refuses the endpoint.
  fdds::DataWriter* writer(const std::string& topic_name, const std::string& type_name) {
    fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
    qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
    fdds::Topic* t = topic(topic_name, type_name);
    return t == nullptr ? nullptr : publisher_->create_datawriter(t, qos);
  }
  fdds::DataReader* reader(const std::string& topic_name, const std::string& type_name) {
    fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
    qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
    fdds::Topic* t = topic(topic_name, type_name);
    return t == nullptr ? nullptr : subscriber_->create_datareader(t, qos);
  }
  const DiscoveryLog& discovery() const { return discovery_; }

 private:
  fdds::Topic* topic(const std::string& topic_name, const std::string& type_name) {
    if (fdds::Topic* existing = participant_->find_topic(topic_name, eprosima::fastrtps::Duration_t(0, 0))) {
      return existing;
    }
    return participant_->create_topic(topic_name, type_name, fdds::TOPIC_QOS_DEFAULT);
  }

  int domain_;
  int participant_id_;
  std::string name_;
  lode::SecuritySpec security_;
  DiscoveryLog discovery_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
};

const std::string kCommandType = "lode::msg::Command";
const std::string kReplyType = "lode::msg::Reply";
const std::string kSampleType = "lode::msg::SignalSample";

class SecurityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (std::system("command -v openssl >/dev/null 2>&1") != 0) {
      skip_reason_ = "openssl is not installed (apt-get install openssl): tools/dds-security/make-lab-certs.sh needs it";
      return;
    }
    std::string dir_template = (std::filesystem::temp_directory_path() / "lode_dds_security_XXXXXX").string();
    if (::mkdtemp(dir_template.data()) == nullptr) {
      setup_error_ = "mkdtemp failed";
      return;
    }
    root_ = dir_template;
    const std::string script = std::string(LODE_SOURCE_DIR) + "/tools/dds-security/make-lab-certs.sh";
    // The lab PKI, and a second, unrelated CA whose documents give `observer` the console
    // role: what someone without the lab CA's key could forge.
    for (const auto& [dir, identities] : {std::pair<std::string, std::string>{"lab", ""},
                                          std::pair<std::string, std::string>{"forged", "observer=console"}}) {
      const std::string log = (root_ / (dir + ".log")).string();
      const std::string command =
          "bash '" + script + "' '" + (root_ / dir).string() + "' " + identities + " >'" + log + "' 2>&1";
      if (std::system(command.c_str()) != 0) {
        std::ifstream in(log);
        std::stringstream text;
        text << in.rdbuf();
        setup_error_ = command + " failed:\n" + text.str();
        return;
      }
    }
  }
  static void TearDownTestSuite() {
    if (!root_.empty()) {
      std::error_code ignored;
      std::filesystem::remove_all(root_, ignored);
    }
  }
  void SetUp() override {
    if (!skip_reason_.empty()) LODE_TOOL_MISSING(skip_reason_);
    ASSERT_TRUE(setup_error_.empty()) << setup_error_;
  }

  static std::string lab(const std::string& file) { return (root_ / "lab" / file).string(); }
  static std::string forged(const std::string& file) { return (root_ / "forged" / file).string(); }

  static lode::SecuritySpec identity(const std::string& name) {
    lode::SecuritySpec spec;
    spec.ca_certificate = lab("ca.cert.pem");
    spec.certificate = lab(name + ".cert.pem");
    spec.private_key = lab(name + ".key.pem");
    spec.governance = lab("governance.p7s");
    spec.permissions = lab("permissions_" + name + ".p7s");
    return spec;
  }

  // Participant ids: each name its own, so that participants of one domain never collide.
  static int participant_id(const std::string& name) {
    static const std::vector<std::string> names{"stage", "console", "observer", "rogue", "intruder"};
    return static_cast<int>(std::find(names.begin(), names.end(), name) - names.begin());
  }
  static std::unique_ptr<Node> start(int domain, const std::string& name, const lode::SecuritySpec& security) {
    auto node = std::make_unique<Node>(domain, participant_id(name), name, security);
    const std::string error = node->start();
    EXPECT_TRUE(error.empty()) << error;
    return error.empty() ? std::move(node) : nullptr;
  }

  static inline std::filesystem::path root_;
  static inline std::string skip_reason_;
  static inline std::string setup_error_;
};

TEST_F(SecurityTest, ConsoleCommandReachesStageAndReplyReachesConsole) {
  const int kDomain = lode::testing::private_dds_domain();
  auto stage = start(kDomain, "stage", identity("stage"));
  auto console = start(kDomain, "console", identity("console"));
  ASSERT_TRUE(stage && console);

  fdds::DataReader* stage_commands = stage->reader(kCommandTopic, kCommandType);
  fdds::DataWriter* stage_replies = stage->writer(kReplyTopic, kReplyType);
  fdds::DataWriter* console_commands = console->writer(kCommandTopic, kCommandType);
  fdds::DataReader* console_replies = console->reader(kReplyTopic, kReplyType);
  ASSERT_NE(stage_commands, nullptr) << "stage may subscribe lode/*/command";
  ASSERT_NE(stage_replies, nullptr) << "stage may publish lode/*";
  ASSERT_NE(console_commands, nullptr) << "console may publish lode/*/command";
  ASSERT_NE(console_replies, nullptr) << "console may subscribe everything";

  ASSERT_TRUE(wait_until([&] { return matched(console_commands) == 1 && matched(stage_replies) == 1; },
                         kMatchTimeout))
      << "console and stage never matched (authentication or permissions failed: see the Fast DDS log)";

  lode::msg::Command command = make_command("console", 7);
  ASSERT_EQ(console_commands->write(&command), true);
  std::vector<lode::msg::Command> received;
  ASSERT_TRUE(wait_until(
      [&] {
        for (auto& c : take_all<lode::msg::Command>(stage_commands)) received.push_back(c);
        return !received.empty();
      },
      10s));
  ASSERT_EQ(received.size(), 1u);
  EXPECT_EQ(received[0].client(), "console");
  EXPECT_EQ(received[0].id(), 7u);
  EXPECT_EQ(received[0].kind(), "status");

  lode::msg::Reply reply;
  reply.client("console");
  reply.id(7);
  reply.ok(true);
  reply.message("running");
  ASSERT_EQ(stage_replies->write(&reply), true);
  std::vector<lode::msg::Reply> replies;
  ASSERT_TRUE(wait_until(
      [&] {
        for (auto& r : take_all<lode::msg::Reply>(console_replies)) replies.push_back(r);
        return !replies.empty();
      },
      10s));
  EXPECT_EQ(replies[0].id(), 7u);
  EXPECT_EQ(replies[0].message(), "running");
}

TEST_F(SecurityTest, ObserverReadsTelemetryButCannotCommand) {
  const int kDomain = lode::testing::private_dds_domain();
  auto stage = start(kDomain, "stage", identity("stage"));
  auto observer = start(kDomain, "observer", identity("observer"));
  ASSERT_TRUE(stage && observer);

  fdds::DataWriter* stage_telemetry = stage->writer(kTelemetryTopic, kSampleType);
  fdds::DataReader* stage_commands = stage->reader(kCommandTopic, kCommandType);
  fdds::DataReader* observer_telemetry = observer->reader(kTelemetryTopic, kSampleType);
  ASSERT_TRUE(stage_telemetry && stage_commands && observer_telemetry);

  ASSERT_TRUE(wait_until([&] { return matched(stage_telemetry) == 1; }, kMatchTimeout))
      << "observer never matched stage's telemetry (authentication failed: see the Fast DDS log)";
  lode::msg::SignalSample sample;
  sample.cycle(42);
  sample.values({1.5, -2.5});
  ASSERT_EQ(stage_telemetry->write(&sample), true);
  std::vector<lode::msg::SignalSample> samples;
  ASSERT_TRUE(wait_until(
      [&] {
        for (auto& s : take_all<lode::msg::SignalSample>(observer_telemetry)) samples.push_back(s);
        return !samples.empty();
      },
      10s));
  EXPECT_EQ(samples[0].cycle(), 42u);
  EXPECT_EQ(samples[0].values(), (std::vector<double>{1.5, -2.5}));

  // The observer's own access control refuses the writer: its permissions deny
  // publishing lode/*/command.
  fdds::DataWriter* observer_commands = observer->writer(kCommandTopic, kCommandType);
  EXPECT_EQ(observer_commands, nullptr) << "observer's permissions deny publishing lode/*/command";
  if (observer_commands != nullptr) {
    // Should the local check ever be skipped, the stage must still refuse it.
    lode::msg::Command command = make_command("observer", 1);
    const auto deadline = Clock::now() + kRefusalWindow;
    while (Clock::now() < deadline) {
      observer_commands->write(&command);
      std::this_thread::sleep_for(100ms);
    }
    EXPECT_EQ(matched(observer_commands), 0);
    EXPECT_EQ(matched(stage_commands), 0);
    EXPECT_TRUE(take_all<lode::msg::Command>(stage_commands).empty());
  }
}

// `observer`'s real certificate with permissions (console role) and governance signed by a
// CA the stage does not trust: the stage refuses the participant, so the command writer
// that its forged documents allow never matches and its commands never arrive.
TEST_F(SecurityTest, ForgedPermissionsAreRefused) {
  const int kDomain = lode::testing::private_dds_domain();
  lode::SecuritySpec rogue_identity = identity("observer");
  rogue_identity.permissions_ca = forged("ca.cert.pem");
  rogue_identity.governance = forged("governance.p7s");
  rogue_identity.permissions = forged("permissions_observer.p7s");

  auto stage = start(kDomain, "stage", identity("stage"));
  auto console = start(kDomain, "console", identity("console"));
  auto rogue = start(kDomain, "rogue", rogue_identity);
  ASSERT_TRUE(stage && console && rogue);

  fdds::DataReader* stage_commands = stage->reader(kCommandTopic, kCommandType);
  fdds::DataWriter* stage_telemetry = stage->writer(kTelemetryTopic, kSampleType);
  fdds::DataWriter* console_commands = console->writer(kCommandTopic, kCommandType);
  fdds::DataWriter* rogue_commands = rogue->writer(kCommandTopic, kCommandType);
  fdds::DataReader* rogue_telemetry = rogue->reader(kTelemetryTopic, kSampleType);
  ASSERT_TRUE(stage_commands && stage_telemetry && console_commands);
  ASSERT_NE(rogue_commands, nullptr) << "the forged permissions allow the writer locally";
  ASSERT_NE(rogue_telemetry, nullptr);

  ASSERT_TRUE(wait_until([&] { return matched(console_commands) == 1; }, kMatchTimeout));
  lode::msg::Command rogue_command = make_command("rogue", 666);
  lode::msg::Command console_command = make_command("console", 1);
  console_commands->write(&console_command);
  const auto deadline = Clock::now() + kRefusalWindow;
  std::vector<lode::msg::Command> received;
  while (Clock::now() < deadline) {
    rogue_commands->write(&rogue_command);
    for (auto& c : take_all<lode::msg::Command>(stage_commands)) received.push_back(c);
    std::this_thread::sleep_for(100ms);
  }
  for (auto& c : take_all<lode::msg::Command>(stage_commands)) received.push_back(c);

  EXPECT_EQ(matched(rogue_commands), 0);
  EXPECT_EQ(matched(rogue_telemetry), 0);
  EXPECT_EQ(matched(stage_commands), 1) << "only the console's writer";
  EXPECT_EQ(matched(stage_telemetry), 0);
  ASSERT_EQ(received.size(), 1u);
  EXPECT_EQ(received[0].client(), "console");
  // Stage sees the rogue's clear-text announcement, then refuses its permissions.
  EXPECT_FALSE(stage->discovery().saw("authorized rogue")) << stage->discovery().events();
  EXPECT_TRUE(stage->discovery().saw("authorized console")) << stage->discovery().events();
  std::cout << "[ info     ] stage: " << stage->discovery().events() << "\n";
}

TEST_F(SecurityTest, ParticipantWithoutSecurityCannotMatchStage) {
  const int kDomain = lode::testing::private_dds_domain();
  auto stage = start(kDomain, "stage", identity("stage"));
  auto console = start(kDomain, "console", identity("console"));
  auto intruder = start(kDomain, "intruder", lode::SecuritySpec{});
  ASSERT_TRUE(stage && console && intruder);

  fdds::DataReader* stage_commands = stage->reader(kCommandTopic, kCommandType);
  fdds::DataWriter* stage_telemetry = stage->writer(kTelemetryTopic, kSampleType);
  fdds::DataReader* console_telemetry = console->reader(kTelemetryTopic, kSampleType);
  fdds::DataWriter* intruder_commands = intruder->writer(kCommandTopic, kCommandType);
  fdds::DataReader* intruder_telemetry = intruder->reader(kTelemetryTopic, kSampleType);
  ASSERT_TRUE(stage_commands && stage_telemetry && console_telemetry && intruder_commands && intruder_telemetry);

  // Positive control: the authenticated console matches, so discovery is running.
  ASSERT_TRUE(wait_until([&] { return matched(console_telemetry) == 1; }, kMatchTimeout));
  lode::msg::Command command = make_command("intruder", 13);
  lode::msg::SignalSample sample;
  sample.values({3.0});
  const auto deadline = Clock::now() + kRefusalWindow;
  while (Clock::now() < deadline) {
    intruder_commands->write(&command);
    stage_telemetry->write(&sample);
    std::this_thread::sleep_for(100ms);
  }

  EXPECT_FALSE(stage->discovery().saw("authorized intruder")) << stage->discovery().events();
  EXPECT_EQ(matched(intruder_commands), 0);
  EXPECT_EQ(matched(intruder_telemetry), 0);
  EXPECT_EQ(matched(stage_commands), 0);
  EXPECT_EQ(matched(stage_telemetry), 1) << "only the console's reader";
  EXPECT_TRUE(take_all<lode::msg::Command>(stage_commands).empty());
  EXPECT_TRUE(take_all<lode::msg::SignalSample>(intruder_telemetry).empty());
  // Secure participants announce themselves (SPDP) in clear text, as the DDS Security spec
  // requires, so the intruder may see that a stage exists; it can do nothing with it.
  std::cout << "[ info     ] stage: " << stage->discovery().events() << "\n"
            << "[ info     ] intruder: " << intruder->discovery().events() << "\n";
}

TEST_F(SecurityTest, DiscoveryTimeWithAndWithoutSecurity) {
  // Time from creating two participants (and their endpoints) to the writer matching the
  // reader, alternating secure and plain rounds; a rough figure, only bounded by the timeout.
  const auto time_to_match = [](int domain, const lode::SecuritySpec& stage_security,
                                const lode::SecuritySpec& console_security) -> double {
    const auto start_time = Clock::now();
    auto stage = start(domain, "stage", stage_security);
    auto console = start(domain, "console", console_security);
    if (!stage || !console) return -1.0;
    fdds::DataReader* reader = stage->reader(kCommandTopic, kCommandType);
    fdds::DataWriter* writer = console->writer(kCommandTopic, kCommandType);
    if (reader == nullptr || writer == nullptr) return -1.0;
    if (!wait_until([&] { return matched(writer) == 1 && matched(reader) == 1; }, kMatchTimeout)) return -1.0;
    return std::chrono::duration<double, std::milli>(Clock::now() - start_time).count();
  };
  constexpr int kRounds = 5;
  const int secure_domain = lode::testing::private_dds_domain();
  const int plain_domain = lode::testing::another_private_dds_domain();
  std::vector<double> secure_ms;
  std::vector<double> plain_ms;
  for (int round = 0; round < kRounds; ++round) {
    secure_ms.push_back(time_to_match(secure_domain, identity("stage"), identity("console")));
    plain_ms.push_back(time_to_match(plain_domain, lode::SecuritySpec{}, lode::SecuritySpec{}));
    ASSERT_GE(secure_ms.back(), 0.0) << "secure participants did not match within 30 s";
    ASSERT_GE(plain_ms.back(), 0.0) << "plain participants did not match within 30 s";
  }
  const auto summary = [](std::vector<double> ms) {
    std::sort(ms.begin(), ms.end());
    std::ostringstream text;
    text.precision(3);
    text << "median " << ms[ms.size() / 2] << " ms (min " << ms.front() << ", max " << ms.back() << ")";
    return text.str();
  };
  RecordProperty("secure_match", summary(secure_ms));
  RecordProperty("plain_match", summary(plain_ms));
  std::cout << "[ info     ] discovery to match over " << kRounds << " rounds: with security " << summary(secure_ms)
            << "; without " << summary(plain_ms) << "\n";
}

TEST_F(SecurityTest, ApplySecurityNamesTheFieldOfABadFile) {
  fdds::DomainParticipantQos qos;
  const std::size_t default_properties = qos.properties().properties().size();

  lode::SecuritySpec missing_key = identity("stage");
  missing_key.private_key = (root_ / "nowhere" / "stage.key.pem").string();
  lode::Status status = lode::dds::apply_security(missing_key, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message(),
            "telemetry.security.private_key: cannot read " + missing_key.private_key + " (No such file or directory)");
  EXPECT_EQ(qos.properties().properties().size(), default_properties) << "a failed call leaves the QoS alone";

  lode::SecuritySpec unsigned_governance = identity("stage");
  unsigned_governance.governance = lab("governance.xml");
  status = lode::dds::apply_security(unsigned_governance, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message().rfind("telemetry.security.governance: " + lab("governance.xml") +
                                       " is not an S/MIME signed document",
                                   0),
            0u)
      << status.message();

  lode::SecuritySpec swapped = identity("stage");
  std::swap(swapped.certificate, swapped.private_key);
  status = lode::dds::apply_security(swapped, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message(), "telemetry.security.certificate: " + swapped.certificate + " is not a PEM certificate");

  lode::SecuritySpec directory = identity("stage");
  directory.permissions_ca = root_.string();
  status = lode::dds::apply_security(directory, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message(), "telemetry.security.permissions_ca: cannot read " + root_.string() +
                                  " (not a regular file)");

  lode::SecuritySpec no_certificate = identity("stage");
  no_certificate.certificate.clear();
  status = lode::dds::apply_security(no_certificate, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message().rfind("telemetry.security.certificate: missing", 0), 0u) << status.message();

  lode::SecuritySpec no_governance = identity("stage");
  no_governance.governance.clear();
  status = lode::dds::apply_security(no_governance, qos);
  ASSERT_FALSE(status);
  EXPECT_EQ(status.message(), "telemetry.security.governance: required when telemetry.security is given");

  EXPECT_TRUE(lode::dds::apply_security(lode::SecuritySpec{}, qos)) << "empty spec = security off";
  EXPECT_EQ(qos.properties().properties().size(), default_properties);

  // A good spec sets the plugins and file:// URIs (permissions_ca defaults to the identity CA).
  ASSERT_TRUE(lode::dds::apply_security(identity("stage"), qos));
  ASSERT_TRUE(lode::dds::apply_security(identity("stage"), qos)) << "applying twice replaces, not appends";
  const auto value_of = [&](const std::string& name) {
    std::string value;
    int count = 0;
    for (const auto& property : qos.properties().properties()) {
      if (property.name() == name) {
        value = property.value();
        ++count;
      }
    }
    return count == 1 ? value : "<" + std::to_string(count) + " properties>";
  };
  EXPECT_EQ(value_of("dds.sec.auth.plugin"), "builtin.PKI-DH");
  EXPECT_EQ(value_of("dds.sec.access.plugin"), "builtin.Access-Permissions");
  EXPECT_EQ(value_of("dds.sec.crypto.plugin"), "builtin.AES-GCM-GMAC");
  EXPECT_EQ(value_of("dds.sec.auth.builtin.PKI-DH.identity_ca"), "file://" + lab("ca.cert.pem"));
  EXPECT_EQ(value_of("dds.sec.auth.builtin.PKI-DH.identity_certificate"), "file://" + lab("stage.cert.pem"));
  EXPECT_EQ(value_of("dds.sec.auth.builtin.PKI-DH.private_key"), "file://" + lab("stage.key.pem"));
  EXPECT_EQ(value_of("dds.sec.access.builtin.Access-Permissions.permissions_ca"), "file://" + lab("ca.cert.pem"));
  EXPECT_EQ(value_of("dds.sec.access.builtin.Access-Permissions.governance"), "file://" + lab("governance.p7s"));
  EXPECT_EQ(value_of("dds.sec.access.builtin.Access-Permissions.permissions"),
            "file://" + lab("permissions_stage.p7s"));
}

}  // namespace
