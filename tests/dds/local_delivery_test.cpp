// Which pipelines deliver to a client through shared memory alone, and the locator such a
// reader announces (core/dds/src/local_delivery.hpp).
#include "local_delivery.hpp"

#include <unistd.h>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/attributes/RTPSParticipantAllocationAttributes.hpp>
#include <gtest/gtest.h>

#include "lode/testing/private_domain.hpp"

namespace {

using eprosima::fastrtps::rtps::GuidPrefix_t;
using eprosima::fastrtps::rtps::ParticipantProxyData;
using eprosima::fastrtps::rtps::RTPSParticipantAllocationAttributes;
using lode::dds::detail::announced_uid;
using lode::dds::detail::shared_memory_reaches_us;

GuidPrefix_t prefix_on_host(std::uint8_t low, std::uint8_t high, std::uint8_t participant) {
  GuidPrefix_t p;
  p.value[0] = 0x01;
  p.value[1] = 0x0f;
  p.value[2] = low;
  p.value[3] = high;
  p.value[8] = participant;
  return p;
}

TEST(LocalDelivery, OnlyAPipelineOfThisUserOnThisHostDeliversThroughSharedMemory) {
  const std::uint32_t me = ::getuid();
  const GuidPrefix_t own = prefix_on_host(0x12, 0x34, 1);
  EXPECT_TRUE(shared_memory_reaches_us(own, prefix_on_host(0x12, 0x34, 2), me));
  EXPECT_FALSE(shared_memory_reaches_us(own, prefix_on_host(0x12, 0x35, 2), me)) << "another host";
  EXPECT_FALSE(shared_memory_reaches_us(own, prefix_on_host(0x13, 0x34, 2), me)) << "another host";
  EXPECT_FALSE(shared_memory_reaches_us(own, prefix_on_host(0x12, 0x34, 2), me + 1)) << "another user";
  if (me != 0) {
    EXPECT_FALSE(shared_memory_reaches_us(own, prefix_on_host(0x12, 0x34, 2), 0u)) << "root";
  }
  EXPECT_FALSE(shared_memory_reaches_us(own, prefix_on_host(0x12, 0x34, 2), std::nullopt))
      << "a participant that does not say who runs it";
}

TEST(LocalDelivery, TheUidIsReadFromTheAnnouncedProperties) {
  RTPSParticipantAllocationAttributes allocation;
  ParticipantProxyData peer(allocation);
  EXPECT_EQ(announced_uid(peer), std::nullopt);
  peer.m_properties.push_back(std::pair<std::string, std::string>{"other", "7"});
  peer.m_properties.push_back(std::pair<std::string, std::string>{lode::dds::detail::kUidProperty, "1000"});
  EXPECT_EQ(announced_uid(peer), std::optional<std::uint32_t>{1000});
  ParticipantProxyData garbled(allocation);
  garbled.m_properties.push_back(std::pair<std::string, std::string>{lode::dds::detail::kUidProperty, "10x"});
  EXPECT_EQ(announced_uid(garbled), std::nullopt);
}

TEST(LocalDelivery, APortIsClaimedBelowFastDdsPortsAndTakenAgainWhenFree) {
  namespace fdds = eprosima::fastdds::dds;
  using lode::dds::detail::SharedMemoryPort;
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  lode::dds::detail::announce_uid(qos);
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipant* participant = factory->create_participant(lode::testing::private_dds_domain(), qos);
  ASSERT_NE(participant, nullptr);
  std::uint32_t first_port = 0;
  {
    auto first = SharedMemoryPort::claim(*participant);
    auto second = SharedMemoryPort::claim(*participant);
    ASSERT_TRUE(first && second);
    const auto& locator = first->locator();
    EXPECT_EQ(locator.kind, LOCATOR_KIND_SHM);
    EXPECT_EQ(locator.address[0], 'U');
    EXPECT_EQ(locator.address[1], participant->guid().guidPrefix.value[2]);
    EXPECT_EQ(locator.address[2], participant->guid().guidPrefix.value[3]);
    EXPECT_GE(locator.port, 1024u);
    EXPECT_LT(locator.port, 7400u) << "below every port Fast DDS numbers itself";
    EXPECT_NE(locator.port, second->locator().port) << "a claimed port is not handed out twice";
    first_port = locator.port;
  }
  // Released with its holder: the lowest free port is taken again (no port left behind).
  auto again = SharedMemoryPort::claim(*participant);
  ASSERT_TRUE(again);
  EXPECT_LE(again->locator().port, first_port);
  factory->delete_participant(participant);
}

}  // namespace
