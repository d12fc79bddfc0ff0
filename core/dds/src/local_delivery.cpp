#include "local_delivery.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <string>

#include <fastrtps/config.h>

namespace lode::dds::detail {

namespace rtps = eprosima::fastrtps::rtps;

void announce_uid(eprosima::fastdds::dds::DomainParticipantQos& qos) {
  qos.properties().properties().emplace_back(kUidProperty, std::to_string(::getuid()), true);
}

std::optional<std::uint32_t> announced_uid(const rtps::ParticipantProxyData& peer) {
  for (const auto& property : peer.m_properties) {
    if (property.first() != kUidProperty) continue;
    const std::string text = property.second();
    std::uint32_t uid = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), uid);
    if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
    return uid;
  }
  return std::nullopt;
}

bool shared_memory_reaches_us(const rtps::GuidPrefix_t& own, const rtps::GuidPrefix_t& peer,
                                 std::optional<std::uint32_t> peer_uid) {
  if (!peer_uid) return false;
  const bool same_host = own.value[2] == peer.value[2] && own.value[3] == peer.value[3];
  return same_host && *peer_uid == ::getuid();
}

namespace {

/// Whether a live process holds shared-memory port `port`: Fast DDS 2.x keeps the file
/// /dev/shm/fastrtps_port<port>_el locked (flock) while a listener has the port, and a
/// process that died releases it (its port is then a zombie Fast DDS takes over).
bool port_held(std::uint32_t port) {
  const std::string lock = "/dev/shm/fastrtps_port" + std::to_string(port) + "_el";
  const int fd = ::open(lock.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool held = ::flock(fd, LOCK_EX | LOCK_NB) != 0;
  if (!held) ::flock(fd, LOCK_UN);
  ::close(fd);
  return held;
}

}  // namespace

std::optional<rtps::Locator_t> shared_memory_locator(const eprosima::fastdds::dds::DomainParticipant& participant) {
#if FASTRTPS_VERSION_MAJOR == 2
  // A port of its own, not the participant's default one: Fast DDS moves a participant's ports
  // past those in use and does not say where they ended up. Above the RTPS ports (<= 65535),
  // 64 per process id; one a live process holds (another PID namespace sharing /dev/shm) is
  // passed over. Fast DDS 2.x lays a shared-memory locator out as 'U' and the host id (the GUID
  // prefix's bytes 2 and 3), which is how the writers tell it is on their host.
  static std::atomic<std::uint32_t> next{0};
  const std::uint32_t first = 0x10000u + static_cast<std::uint32_t>(::getpid()) * 64u;
  for (int tries = 0; tries < 64; ++tries) {
    const std::uint32_t port = first + next.fetch_add(1) % 64u;
    if (port_held(port)) continue;
    const rtps::GuidPrefix_t& prefix = participant.guid().guidPrefix;
    rtps::Locator_t locator(LOCATOR_KIND_SHM, port);
    locator.address[0] = 'U';
    locator.address[1] = prefix.value[2];
    locator.address[2] = prefix.value[3];
    return locator;
  }
  return std::nullopt;
#else
  (void)participant;
  return std::nullopt;
#endif
}

}  // namespace lode::dds::detail
