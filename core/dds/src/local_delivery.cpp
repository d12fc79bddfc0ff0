#include "local_delivery.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

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

// Ports 1024 to 7399: Fast DDS numbers its own from 7400 up (the RTPS port base), so none of
// its participants takes one of these; 4 digits, so `fastdds shm clean` recognises a port a
// killed client left behind, and the lowest free one is taken, so the next client takes such
// a port over instead of leaving another.
constexpr std::uint32_t kFirstPort = 1024, kEndPort = 7400;

}  // namespace

std::optional<SharedMemoryPort> SharedMemoryPort::claim(const eprosima::fastdds::dds::DomainParticipant& participant) {
#if FASTRTPS_VERSION_MAJOR == 2
  // A port of its own, not the participant's default one: Fast DDS moves a participant's ports
  // past those in use and does not say where they ended up. A lodestone client claims a port
  // with an flock on /dev/shm/lode_shm_port<N>_claim for as long as it uses the port (two
  // clients starting together cannot take the same one; a killed one releases it), and passes
  // over one whose Fast DDS lock is held (any other process listening there).
  for (std::uint32_t port = kFirstPort; port < kEndPort; ++port) {
    const std::string claim = "/dev/shm/lode_shm_port" + std::to_string(port) + "_claim";
    const int fd = ::open(claim.c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0 || port_held(port)) {
      ::close(fd);
      continue;
    }
    // Fast DDS 2.x lays a shared-memory locator out as 'U' and the host id (the GUID prefix's
    // bytes 2 and 3), which is how the writers tell it is on their host.
    const rtps::GuidPrefix_t& prefix = participant.guid().guidPrefix;
    rtps::Locator_t locator(LOCATOR_KIND_SHM, port);
    locator.address[0] = 'U';
    locator.address[1] = prefix.value[2];
    locator.address[2] = prefix.value[3];
    return SharedMemoryPort(locator, fd);
  }
  return std::nullopt;
#else
  (void)participant;
  return std::nullopt;
#endif
}

SharedMemoryPort::SharedMemoryPort(SharedMemoryPort&& other) noexcept
    : locator_(other.locator_), claim_fd_(other.claim_fd_) {
  other.claim_fd_ = -1;
}

SharedMemoryPort& SharedMemoryPort::operator=(SharedMemoryPort&& other) noexcept {
  if (this != &other) {
    if (claim_fd_ >= 0) ::close(claim_fd_);
    locator_ = other.locator_;
    claim_fd_ = other.claim_fd_;
    other.claim_fd_ = -1;
  }
  return *this;
}

SharedMemoryPort::~SharedMemoryPort() {
  if (claim_fd_ >= 0) ::close(claim_fd_);
}

}  // namespace lode::dds::detail
