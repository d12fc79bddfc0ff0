// A pipeline's samples to a client on the same host through shared memory alone.
//
// A loopback participant has two transports, shared memory and UDP on 127.0.0.1, and its
// readers announce a unicast locator of each. Fast DDS 2.9 sends a sample to every locator a
// reader announces: each sample a pipeline published reached `lode echo` twice, once through
// shared memory and once as a datagram it then discarded, and the pipeline's publisher thread
// paid a sendto() per sample and subscriber for the second copy (its write() took 35-38 us
// instead of 12-21 us at 1 kHz on a 2-core VM).
//
// A client's sample reader therefore announces a shared-memory port alone when the pipeline
// runs on this host as the same user: Fast DDS 2.9 creates its ports and segments readable and
// writable by their owner only, and a reader maps the writer's segment read-write, so even a
// pipeline run by root cannot deliver to another user's reader this way. Every participant
// says who runs it in a propagated property. Otherwise (another user, another host, a
// pipeline of another version, another DDS) the reader listens on UDP. Private to
// lodestone_dds.
#pragma once

#include <cstdint>
#include <optional>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/rtps/builtin/data/ParticipantProxyData.h>
#include <fastdds/rtps/common/Locator.h>

namespace lode::dds::detail {

/// The property every lodestone participant announces: the uid of the user running it.
inline constexpr const char* kUidProperty = "lode.uid";

/// Add kUidProperty (this process's uid) to the properties `qos` announces.
void announce_uid(eprosima::fastdds::dds::DomainParticipantQos& qos);

/// The uid a discovered participant announced, if it did.
std::optional<std::uint32_t> announced_uid(const eprosima::fastrtps::rtps::ParticipantProxyData& peer);

/// Whether the participant `peer` (announcing `peer_uid`) can deliver through the shared memory
/// of this process, whose participant is `own`: on this host (Fast DDS puts the host in bytes 2
/// and 3 of every GUID prefix) and run by this user.
bool shared_memory_reaches_us(const eprosima::fastrtps::rtps::GuidPrefix_t& own,
                                 const eprosima::fastrtps::rtps::GuidPrefix_t& peer,
                                 std::optional<std::uint32_t> peer_uid);

/// A shared-memory port of this process's own, for a participant's readers to announce alone
/// (every reader of a participant shares it: each port has a listening thread), held until
/// destroyed.
class SharedMemoryPort {
 public:
  /// A free port below Fast DDS's RTPS ports, or nullopt where the Fast DDS in use is not of the
  /// 2.x series (whose locators this builds the way its shared-memory transport does) or none
  /// is free.
  static std::optional<SharedMemoryPort> claim(const eprosima::fastdds::dds::DomainParticipant& participant);
  SharedMemoryPort(SharedMemoryPort&& other) noexcept;
  SharedMemoryPort& operator=(SharedMemoryPort&& other) noexcept;
  SharedMemoryPort(const SharedMemoryPort&) = delete;
  ~SharedMemoryPort();
  [[nodiscard]] const eprosima::fastrtps::rtps::Locator_t& locator() const { return locator_; }

 private:
  SharedMemoryPort(eprosima::fastrtps::rtps::Locator_t locator, int claim_fd) : locator_(locator), claim_fd_(claim_fd) {}
  eprosima::fastrtps::rtps::Locator_t locator_;
  int claim_fd_ = -1;
};

}  // namespace lode::dds::detail
