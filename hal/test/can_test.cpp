// CAN frame decoding and the CANopen helpers (hal/include/lode/hal/can_frame.hpp, canopen.hpp).
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>

#include <chrono>
#include <cstring>
#include <string>
#include <thread>

#include "lode/hal/can_frame.hpp"
#include "lode/sdk/clock.hpp"
#include "lode/hal/can_socket.hpp"
#include "lode/hal/canopen.hpp"

namespace {

using lode::hal::CanFrame;
namespace co = lode::hal::canopen;

std::string decode_reason(const struct can_frame& k) {
  CanFrame f;
  const char* why = lode::hal::decode_can_frame(reinterpret_cast<const std::uint8_t*>(&k), sizeof k, f);
  return why ? why : "";
}

TEST(CanFrame, KernelFramesDecodeAndEncodeBack) {
  struct can_frame k {};
  k.can_id = 0x18a;
  k.len = 4;
  const std::uint8_t payload[4] = {1, 2, 3, 4};
  std::memcpy(k.data, payload, 4);
  CanFrame f;
  ASSERT_EQ(lode::hal::decode_can_frame(reinterpret_cast<const std::uint8_t*>(&k), sizeof k, f), nullptr);
  EXPECT_EQ(f.id, 0x18au);
  EXPECT_FALSE(f.extended || f.remote || f.error);
  EXPECT_EQ(f.length, 4);
  EXPECT_EQ(f.data[3], 4);
  struct can_frame back {};
  lode::hal::encode_can_frame(f, reinterpret_cast<std::uint8_t*>(&back));
  EXPECT_EQ(std::memcmp(&k, &back, sizeof k), 0);

  k.can_id = 0x1F334455u | CAN_EFF_FLAG;
  ASSERT_EQ(decode_reason(k), "");
  ASSERT_EQ(lode::hal::decode_can_frame(reinterpret_cast<const std::uint8_t*>(&k), sizeof k, f), nullptr);
  EXPECT_TRUE(f.extended);
  EXPECT_EQ(f.id, 0x1F334455u);
}

TEST(CanFrame, MalformedBytesGiveAReason) {
  struct can_frame k {};
  k.can_id = 0x123;
  k.len = 9;
  EXPECT_EQ(decode_reason(k), "data length over 8 bytes");
  k.len = 2;
  k.can_id = 0x800;  // 12 bits in a standard frame
  EXPECT_EQ(decode_reason(k), "standard frame with an identifier over 11 bits");
  k.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  k.len = 2;
  EXPECT_EQ(decode_reason(k), "error frame without its 8 data bytes");
  CanFrame f;
  const std::uint8_t short_bytes[8] = {};
  EXPECT_STREQ(lode::hal::decode_can_frame(short_bytes, sizeof short_bytes, f),
               "not a classic CAN frame (a struct can_frame is 16 bytes)");
}

TEST(CanFrame, ErrorFramesNameTheWorstCondition) {
  struct can_frame k {};
  k.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF | CAN_ERR_CRTL;
  k.len = CAN_ERR_DLC;
  k.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  CanFrame f;
  ASSERT_EQ(lode::hal::decode_can_frame(reinterpret_cast<const std::uint8_t*>(&k), sizeof k, f), nullptr);
  auto e = lode::hal::summarize_error(f);
  EXPECT_TRUE(e.bus_off);
  EXPECT_TRUE(e.error_passive);
  EXPECT_STREQ(e.worst, "CAN bus-off: the controller left the bus");
  k.can_id = CAN_ERR_FLAG | CAN_ERR_ACK;
  ASSERT_EQ(lode::hal::decode_can_frame(reinterpret_cast<const std::uint8_t*>(&k), sizeof k, f), nullptr);
  e = lode::hal::summarize_error(f);
  EXPECT_FALSE(e.bus_off);
  EXPECT_STREQ(e.worst, "CAN frames not acknowledged (no other node on the bus?)");
}

TEST(CanOpen, PredefinedConnectionSet) {
  EXPECT_EQ(co::tpdo_cob(1, 5), 0x185u);
  EXPECT_EQ(co::tpdo_cob(4, 5), 0x485u);
  EXPECT_EQ(co::rpdo_cob(1, 5), 0x205u);
  EXPECT_EQ(co::rpdo_cob(2, 127), 0x37fu);
  EXPECT_EQ(co::emcy_cob(5), 0x85u);
  EXPECT_EQ(co::heartbeat_cob(5), 0x705u);
  const CanFrame start = co::nmt_frame(co::NmtCommand::start, 5);
  EXPECT_EQ(start.id, 0u);
  EXPECT_EQ(start.length, 2);
  EXPECT_EQ(start.data[0], 0x01);
  EXPECT_EQ(start.data[1], 5);
  EXPECT_EQ(co::sync_frame().id, 0x80u);
  EXPECT_EQ(co::sync_frame().length, 0);
}

TEST(CanOpen, HeartbeatAndEmergencyDecode) {
  co::NmtState s{};
  ASSERT_TRUE(co::decode_heartbeat(co::heartbeat_frame(5, co::NmtState::operational), s));
  EXPECT_EQ(s, co::NmtState::operational);
  CanFrame bad = co::heartbeat_frame(5, co::NmtState::operational);
  bad.data[0] = 0x33;
  EXPECT_FALSE(co::decode_heartbeat(bad, s));
  bad.length = 2;
  EXPECT_FALSE(co::decode_heartbeat(bad, s));
  CanFrame emcy;
  emcy.id = co::emcy_cob(5);
  emcy.length = 8;
  const std::uint8_t bytes[8] = {0x10, 0x23, 0x04, 1, 2, 3, 4, 5};  // 0x2310: output current too high
  std::memcpy(emcy.data, bytes, 8);
  co::Emergency e;
  ASSERT_TRUE(co::decode_emergency(emcy, e));
  EXPECT_EQ(e.error_code, 0x2310);
  EXPECT_EQ(e.error_register, 0x04);
  EXPECT_EQ(e.vendor[4], 5);
}

TEST(CanOpen, PdoCodecRoundTripsSignedAndUnsignedEntries) {
  co::PdoMapping m;
  m.pdo = 1;
  m.entries = {{"a1", 16, true}, {"b1", 16, true}, {"status", 8, false}, {"count", 8, false}, {"c1", 16, true}};
  ASSERT_TRUE(co::validate(m));
  EXPECT_EQ(m.bytes(), 8u);
  const std::int64_t in[5] = {-32768, 32767, 255, 0, -1};
  CanFrame f;
  co::pack_pdo(m, in, f);
  EXPECT_EQ(f.length, 8);
  EXPECT_EQ(f.data[0], 0x00);
  EXPECT_EQ(f.data[1], 0x80);  // little endian
  std::int64_t out[5] = {};
  ASSERT_EQ(co::unpack_pdo(m, f, out), nullptr);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(out[i], in[i]) << i;
  co::PdoMapping wide;
  wide.entries = {{"x", 32, true}, {"y", 32, false}};
  const std::int64_t w[2] = {-2000000000, 4000000000};
  co::pack_pdo(wide, w, f);
  std::int64_t wo[2] = {};
  ASSERT_EQ(co::unpack_pdo(wide, f, wo), nullptr);
  EXPECT_EQ(wo[0], w[0]);
  EXPECT_EQ(wo[1], w[1]);
}

TEST(CanOpen, MalformedPdosAndMappingsAreRefused) {
  co::PdoMapping m;
  m.entries = {{"a1", 16, true}, {"b1", 16, true}};
  CanFrame f;
  f.length = 6;  // the module sent 6 bytes; the mapping has 4
  std::int64_t out[2];
  EXPECT_STREQ(co::unpack_pdo(m, f, out), "PDO length does not match its mapping");
  f.length = 4;
  f.remote = true;
  EXPECT_STREQ(co::unpack_pdo(m, f, out), "not a data frame");
  co::PdoMapping bad;
  bad.entries = {{"a", 12, true}};
  EXPECT_NE(co::validate(bad).message().find("entry 'a': bits must be 8, 16 or 32, got 12"), std::string::npos);
  bad.entries = {{"a", 32, true}, {"b", 32, true}, {"c", 8, true}};
  EXPECT_NE(co::validate(bad).message().find("maps 72 bits: a CAN frame carries at most 64"), std::string::npos);
  bad.entries = {};
  EXPECT_FALSE(co::validate(bad));
  bad.entries = {{"a", 8, true}};
  bad.pdo = 5;
  EXPECT_FALSE(co::validate(bad));
}

}  // namespace

// A frame carries the kernel's receive time (SO_TIMESTAMPNS, CLOCK_REALTIME): after the send,
// before the read, and not the time of the read when the reader comes late.
TEST(CanSocket, FramesCarryTheKernelReceiveTime) {
  auto bus = lode::hal::CanSocket::pair();
  ASSERT_TRUE(bus) << bus.error();
  auto& [a, b] = *bus;
  lode::hal::CanFrame sent;
  sent.id = 0x185;
  sent.length = 2;
  const std::int64_t before = lode::realtime_ns();
  ASSERT_TRUE(a.send(sent));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::int64_t read_at = lode::realtime_ns();
  lode::hal::CanFrame got;
  const char* why = nullptr;
  ASSERT_EQ(b.receive(got, why), lode::hal::CanSocket::Receive::frame) << (why ? why : "");
  EXPECT_EQ(got.id, 0x185u);
  EXPECT_GE(got.timestamp_ns, before);
  EXPECT_LT(got.timestamp_ns, read_at) << "the time the frame arrived, not the time it was read";
  EXPECT_GT(read_at - got.timestamp_ns, 15'000'000) << "sent 20 ms before the read";
}
