// Participants with lodestone's transports. The default ("loopback") never sends a packet
// off this host: shared memory for data, UDPv4 on 127.0.0.1 with unicast discovery to
// 127.0.0.1 and no multicast. "network" is the only kind that touches a NIC.
#include "lode/dds/participant.hpp"

#include <arpa/inet.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include "local_delivery.hpp"
#include "shared_memory_leftovers.hpp"
#include "security.hpp"

namespace lode::dds {

namespace fdds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;

namespace {

// Unicast discovery sends to the well-known ports of participant ids 0..N-1 on each
// initial peer. Fast DDS's default (4) is too few when a pipeline, a recorder and several
// `lode echo` run on one host in one domain. On 127.0.0.1 it is generous because Fast DDS
// 2.9 numbers participants per process and never reuses a number: two participants of one
// long-lived process (a test) with ids beyond the range cannot find each other. A few
// dozen datagrams on lo every announcement period cost nothing.
constexpr std::uint32_t kLoopbackPeersRange = 64;
constexpr std::uint32_t kNetworkPeersRange = 16;

/// `wanted` initial peers per address, or fewer where the highest domains leave no room: the
/// RTPS port of participant p in domain d is 7400 + 250 d + 11 + 2 p (user unicast, the
/// highest of its ports), and a port past 65535 makes Fast DDS refuse the participant. In
/// domain 232 that is participants 0..62.
std::uint32_t peers_range(int domain, std::uint32_t wanted) {
  constexpr int kHighestPort = 65535, kPortBase = 7400, kDomainGain = 250, kUserUnicastOffset = 11,
                kParticipantGain = 2;
  const int room = (kHighestPort - kPortBase - kDomainGain * domain - kUserUnicastOffset) / kParticipantGain + 1;
  return std::min(wanted, static_cast<std::uint32_t>(std::max(room, 1)));
}
constexpr std::int32_t kAnnouncementPeriodS = 1;
// Shared memory between the processes of one host. A best-effort sample is lost when the
// reader's port queue is full (its process did not run) or the writer's segment has no free
// buffer (a reader still holds them). Fast DDS's defaults, 512 descriptors and 512 KiB, are
// 90 ms of a pipeline publishing 7 topics at 800 Hz: `lode record` beside a loop on a busy
// 2-core host lost samples in bursts. 8192 descriptors and 8 MiB hold more than a second of
// that; the segment is touched only as far as it is used.
constexpr std::uint32_t kSharedMemoryPortQueue = 8192;
constexpr std::uint32_t kSharedMemorySegmentBytes = 8u << 20;
// How long a process that opens another's shared-memory port may take to find its listener
// alive. Fast DDS 2.9 stores it in the port when the port is created, and its listener wakes
// every third of it to show it is alive; every second some process's watchdog verifies the
// port, and from then until the listener's next wake-up a newcomer's check fails and sleeps
// that third before it tries again. The newcomer opens a port at its first message to it,
// on the participant's event thread with the reader's lock held: with Fast DDS's 1000 ms,
// 2 or 3 in 20 `lode echo` started beside a pipeline sent their first ACKNACK to it
// 333 ms late and had their first sample after 440 to 530 ms instead of ~150 ms. 150 ms bounds
// that sleep to 50 ms, and makes it rarer (the wait after a verification is shorter), for
// 20 idle wake-ups a second per port. A listener that does not run for the whole 150 ms
// after a verification fails the check: the opener then recreates the port, and the owner
// takes it up again at its next wake-up (messages sent to the old one in between are lost).
constexpr std::uint32_t kSharedMemoryHealthCheckMs = 150;
// UDP on this host carries a pipeline's samples to the clients of other users (a `lode
// record` receives ~5600 datagrams a second of kawato_planar that way): with the kernel's
// default receive buffer (208 KiB, a few hundred datagrams) a reader that did not run for a
// few tens of milliseconds lost bursts of them (RcvbufErrors). 4 MiB, as far as
// net.core.rmem_max allows.
constexpr std::uint32_t kUdpReceiveBufferBytes = 4u << 20;

bool parse_ipv4(const std::string& text, std::uint8_t out[4]) {
  in_addr address{};
  if (inet_pton(AF_INET, text.c_str(), &address) != 1) return false;
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(&address.s_addr);
  for (int i = 0; i < 4; ++i) out[i] = bytes[i];
  return true;
}

rtps::Locator_t udp_locator(const std::uint8_t ip[4], std::uint32_t port) {
  rtps::Locator_t locator;
  locator.kind = LOCATOR_KIND_UDPv4;
  rtps::IPLocator::setIPv4(locator, ip[0], ip[1], ip[2], ip[3]);
  locator.port = port;  // 0: the well-known ports of the domain
  return locator;
}

/// "10.0.0.2" or "10.0.0.2:7412".
Status parse_peer(const std::string& text, const std::string& field, rtps::Locator_t& out) {
  std::string host = text;
  std::uint32_t port = 0;
  if (const auto colon = text.find(':'); colon != std::string::npos) {
    host = text.substr(0, colon);
    const std::string port_text = text.substr(colon + 1);
    char* end = nullptr;
    const long value = std::strtol(port_text.c_str(), &end, 10);
    if (port_text.empty() || *end != '\0' || value < 1 || value > 65535) {
      return Status::error(field + ": '" + text + "' has an invalid port (expected 1..65535)");
    }
    port = static_cast<std::uint32_t>(value);
  }
  std::uint8_t ip[4];
  if (!parse_ipv4(host, ip)) {
    return Status::error(field + ": '" + text +
                         "' is not an IPv4 address (expected e.g. 10.0.0.2 or 10.0.0.2:7412)");
  }
  out = udp_locator(ip, port);
  return Status::ok();
}

std::vector<std::string> split_list(const char* text) {
  std::vector<std::string> items;
  if (text == nullptr) return items;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    const auto first = item.find_first_not_of(" \t");
    const auto last = item.find_last_not_of(" \t");
    if (first != std::string::npos) items.push_back(item.substr(first, last - first + 1));
  }
  return items;
}

std::string default_client_name() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return "lode-" + std::to_string(getpid()) + "@" + (host[0] ? host : "localhost");
}

}  // namespace

Status configure_participant_qos(const ParticipantOptions& options, fdds::DomainParticipantQos& qos) {
  if (options.domain < 0 || options.domain > 232) {
    return Status::error("telemetry.domain: " + std::to_string(options.domain) +
                         " is out of range (DDS domain ids are 0..232)");
  }
  qos.name(options.name);
  detail::announce_uid(qos);
  auto& transport = qos.transport();
  auto& builtin = qos.wire_protocol().builtin;
  transport.use_builtin_transports = false;
  transport.user_transports.clear();
  builtin.initialPeersList.clear();
  builtin.metatrafficUnicastLocatorList.clear();
  builtin.metatrafficMulticastLocatorList.clear();
  // Announce every second (Fast DDS's default is 3 s): a command-line client that must know
  // every pipeline live on the domain before it may pick one hears each at least twice within
  // 2.5 s of joining. A few dozen small datagrams a second on a lab network.
  builtin.discovery_config.leaseDuration_announcementperiod = eprosima::fastrtps::Duration_t(kAnnouncementPeriodS, 0);

  const std::uint8_t localhost[4] = {127, 0, 0, 1};
  const auto loopback_udp = [&] {
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->receiveBufferSize = kUdpReceiveBufferBytes;
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    udp->maxInitialPeersRange = peers_range(options.domain, kLoopbackPeersRange);
    transport.user_transports.push_back(udp);
    // Unicast discovery only: an explicit metatraffic locator means no SPDP multicast.
    builtin.initialPeersList.push_back(udp_locator(localhost, 0));
    builtin.metatrafficUnicastLocatorList.push_back(udp_locator(localhost, 0));
  };
  const auto shared_memory = [&] {
    // Before this process adds its own: what killed ones left (shared_memory_leftovers.hpp).
    detail::remove_dead_shared_memory_once();
    auto shm = std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>();
    shm->segment_size(kSharedMemorySegmentBytes);
    shm->port_queue_capacity(kSharedMemoryPortQueue);
    shm->healthy_check_timeout_ms(kSharedMemoryHealthCheckMs);
    transport.user_transports.push_back(shm);
  };

  const TransportSpec& spec = options.transport;
  switch (spec.kind) {
    case TransportSpec::Kind::loopback:
      shared_memory();
      loopback_udp();
      // A client's readers announce UDP alone unless told otherwise (local_delivery.hpp): a
      // shared-memory locator another user's pipeline finds in its discovery data breaks that
      // pipeline's discovery of the client in Fast DDS 2.9 (it cannot open the client's port
      // and segment), and the client then sees no pipeline at all.
      if (options.client) qos.wire_protocol().default_unicast_locator_list.push_back(udp_locator(localhost, 0));
      break;
    case TransportSpec::Kind::shm:
      shared_memory();
      break;
    case TransportSpec::Kind::udp_loopback:
      loopback_udp();
      break;
    case TransportSpec::Kind::network: {
      auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
      udp->receiveBufferSize = kUdpReceiveBufferBytes;
      udp->maxInitialPeersRange = peers_range(options.domain, kNetworkPeersRange);
      std::vector<rtps::Locator_t> interface_locators;
      for (std::size_t i = 0; i < spec.interfaces.size(); ++i) {
        std::uint8_t ip[4];
        if (!parse_ipv4(spec.interfaces[i], ip)) {
          return Status::error("telemetry.network.interfaces[" + std::to_string(i) + "]: '" +
                               spec.interfaces[i] +
                               "' is not an IPv4 address (give the address of the NIC, e.g. 10.0.0.1)");
        }
        udp->interfaceWhiteList.push_back(spec.interfaces[i]);
        interface_locators.push_back(udp_locator(ip, 0));
      }
      for (std::size_t i = 0; i < spec.initial_peers.size(); ++i) {
        rtps::Locator_t peer;
        if (Status s = parse_peer(spec.initial_peers[i],
                                  "telemetry.network.initial_peers[" + std::to_string(i) + "]", peer);
            !s) {
          return s;
        }
        builtin.initialPeersList.push_back(peer);
      }
      if (!spec.multicast) {
        // Explicit unicast metatraffic locators switch SPDP multicast off; address 0.0.0.0
        // lets Fast DDS use every (allowed) interface.
        if (interface_locators.empty()) {
          const std::uint8_t any[4] = {0, 0, 0, 0};
          interface_locators.push_back(udp_locator(any, 0));
        }
        for (const auto& locator : interface_locators) builtin.metatrafficUnicastLocatorList.push_back(locator);
      }
      transport.user_transports.push_back(udp);
      shared_memory();  // peers on this host
      break;
    }
  }

  if (options.security.enabled()) {
    if (Status s = apply_security(options.security, qos); !s) return s;
  }
  return Status::ok();
}

namespace {
constexpr std::string_view kPipelinePrefix = "lode-run/";
}  // namespace

std::string pipeline_participant_name(const std::string& pipeline, const std::string& host) {
  return std::string(kPipelinePrefix) + pipeline + "@" + host;
}

std::optional<std::string> pipeline_of_participant(const std::string& participant_name) {
  if (participant_name.rfind(kPipelinePrefix, 0) != 0) return std::nullopt;
  const auto at = participant_name.rfind('@');
  if (at == std::string::npos || at <= kPipelinePrefix.size()) return std::nullopt;
  return participant_name.substr(kPipelinePrefix.size(), at - kPipelinePrefix.size());
}

Expected<fdds::DomainParticipant*> create_participant(const ParticipantOptions& options,
                                                      fdds::DomainParticipantListener* listener) {
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  if (Status s = configure_participant_qos(options, qos); !s) return s;
  fdds::DomainParticipant* participant =
      fdds::DomainParticipantFactory::get_instance()->create_participant(
          static_cast<fdds::DomainId_t>(options.domain), qos, listener, fdds::StatusMask::none());
  if (participant == nullptr) {
    return Status::error(std::string("could not create a DDS participant '") + options.name +
                         "' on domain " + std::to_string(options.domain) + " with transport " +
                         to_string(options.transport.kind) +
                         (options.security.enabled() ? " and DDS Security (check the certificates)" : ""));
  }
  return participant;
}

void delete_participant(fdds::DomainParticipant* participant) {
  if (participant == nullptr) return;
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
}

std::optional<int> domain_from_environment() {
  const char* domain = std::getenv("LODE_DDS_DOMAIN");
  if (domain == nullptr || *domain == '\0') return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(domain, &end, 10);
  if (*end != '\0' || errno == ERANGE || value < std::numeric_limits<int>::min() ||
      value > std::numeric_limits<int>::max())
    return -1;
  return static_cast<int>(value);
}

ParticipantOptions options_from_environment(const std::string& name) {
  ParticipantOptions options;
  options.name = name.empty() ? default_client_name() : name;
  // Out of range or not a number: kept, so configure_participant_qos names the problem.
  if (const auto domain = domain_from_environment()) options.domain = *domain;
  if (const char* kind = std::getenv("LODE_DDS_TRANSPORT"); kind != nullptr)
    options.transport.kind = transport_kind_from(kind).value_or(TransportSpec::Kind::loopback);  // unknown: loopback
  options.transport.initial_peers = split_list(std::getenv("LODE_DDS_PEERS"));
  options.transport.interfaces = split_list(std::getenv("LODE_DDS_INTERFACES"));
  return options;
}

}  // namespace lode::dds
