// The bytes lodestone puts on the wire, as another DDS implementation (or an older lode) must
// find them: every type is plain CDR (XCDR1, encapsulation CDR_LE, 8-byte values aligned to
// 8), and the key of lode/signals travels as itself in the key hash, which is how a reader
// that never saw the sample maps a dispose to its instance.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "common.hpp"  // detail::topic_id
#include "lode_msgsPubSubTypes.h"

namespace {

/// Expected serialization: little-endian values, padding marked (its bytes are unspecified).
struct Expected {
  std::vector<std::uint8_t> bytes;
  std::vector<bool> padding;
  template <typename T>
  Expected& le(T value) {
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));  // the test host is little endian, like the RT hosts
    for (std::uint8_t b : raw) push(b, false);
    return *this;
  }
  Expected& text(const std::string& s) {  // CDR string: length with the NUL, chars, NUL
    le<std::uint32_t>(static_cast<std::uint32_t>(s.size() + 1));
    for (char c : s) push(static_cast<std::uint8_t>(c), false);
    push(0, false);
    return *this;
  }
  Expected& pad(int n) {
    for (int i = 0; i < n; ++i) push(0, true);
    return *this;
  }
  void push(std::uint8_t b, bool is_padding) {
    bytes.push_back(b);
    padding.push_back(is_padding);
  }
};

template <typename PubSubType, typename Message>
std::vector<std::uint8_t> serialize(Message& message) {
  PubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&message)());
  EXPECT_TRUE(type.serialize(&message, &payload));
  return {payload.data, payload.data + payload.length};
}

void expect_bytes(const std::vector<std::uint8_t>& actual, const Expected& expected) {
  ASSERT_EQ(actual.size(), expected.bytes.size()) << "serialized size";
  for (std::size_t i = 0; i < actual.size(); ++i) {
    if (!expected.padding[i]) {
      EXPECT_EQ(actual[i], expected.bytes[i]) << "byte " << i << " (offset " << static_cast<long>(i) - 4
                                              << " after the encapsulation header)";
    }
  }
}

// 00 01 = CDR_LE, plain (XCDR1) CDR; XCDR2 would be 00 07 (PLAIN_CDR2_LE) or 00 09 (DELIMITED).
Expected cdr_le_header() {
  Expected e;
  e.push(0x00, false);
  e.push(0x01, false);
  e.push(0x00, false);
  e.push(0x00, false);
  return e;
}

TEST(WireFormat, SignalSampleIsPlainCdrWithDoublesAlignedToEight) {
  lode::msg::SignalSample s;
  s.cycle(0x0102030405060708ULL);
  s.stamp_ns(-2);
  s.captured_ns(3);
  s.values({1.5, -0.25});
  Expected e = cdr_le_header();
  e.le<std::uint64_t>(0x0102030405060708ULL).le<std::int64_t>(-2).le<std::int64_t>(3);
  e.le<std::uint32_t>(2).pad(4);  // XCDR1: a double starts at a multiple of 8 (XCDR2: of 4)
  e.le(1.5).le(-0.25);
  expect_bytes(serialize<lode::msg::SignalSamplePubSubType>(s), e);
}

TEST(WireFormat, ReplyStringsAndBooleanAsCyclonesReaderExpectsThem) {
  lode::msg::Reply r;
  r.client("c");
  r.id(7);
  r.ok(true);
  r.message("m");
  r.value("");  // an empty string is length 1 and its NUL: a length of 0 is malformed CDR
  Expected e = cdr_le_header();
  e.text("c").pad(2).le<std::uint64_t>(7).le<std::uint8_t>(1).pad(3).text("m").pad(2).text("");
  expect_bytes(serialize<lode::msg::ReplyPubSubType>(r), e);
}

TEST(WireFormat, TopicIdIsXxh64OfTheTopicName) {
  // The published test vectors of XXH64 with seed 0: anybody can compute the key.
  EXPECT_EQ(lode::dds::detail::topic_id(""), 0xEF46DB3751D8E999ULL);
  EXPECT_EQ(lode::dds::detail::topic_id("abc"), 0x44BC2CF5AD770999ULL);
  EXPECT_NE(lode::dds::detail::topic_id("lode/p/a/out"), lode::dds::detail::topic_id("lode/p/b/out"));
}

TEST(WireFormat, SignalInfoKeyHashIsTheKeyItselfNotAnMd5) {
  lode::msg::SignalInfoPubSubType type;
  ASSERT_LE(lode::msg::SignalInfo::getKeyMaxCdrSerializedSize(), 16u)
      << "a key longer than 16 bytes is sent as its MD5, which no reader can turn back into the key";
  lode::msg::SignalInfo info;
  info.topic("lode/kawato_planar/kf/pose");
  info.topic_id(lode::dds::detail::topic_id(info.topic()));
  eprosima::fastrtps::rtps::InstanceHandle_t handle;
  ASSERT_TRUE(type.getKey(&info, &handle, false));
  std::uint8_t expected[16] = {};
  for (int i = 0; i < 8; ++i) expected[i] = static_cast<std::uint8_t>(info.topic_id() >> (56 - 8 * i));  // big endian
  for (int i = 0; i < 16; ++i) EXPECT_EQ(handle.value[i], expected[i]) << "key hash byte " << i;
  // The topic name is an ordinary field: two samples with the same id are one instance.
  lode::msg::SignalInfo other = info;
  other.topic("renamed");
  eprosima::fastrtps::rtps::InstanceHandle_t other_handle;
  ASSERT_TRUE(type.getKey(&other, &other_handle, false));
  EXPECT_EQ(handle, other_handle);
}

}  // namespace
