// A hostile writer: joins the domain as any participant can, registers a type under one of
// lodestone's type names whose "serialization" is a chosen byte string, and writes samples
// that are not what lode_msgs.idl says. The malformed-sample test points it at a running
// pipeline's command topic and at a `lode echo`'s signal and metadata topics.
//
// usage: malformed_sender DOMAIN LAYOUT TOPIC
//   LAYOUT command  lode::msg::Command on TOPIC: XCDR2 encapsulation, truncated body, a
//                   string length of 2^31, and a string without its terminator (which
//                   Fast CDR decodes as the string without it: sent last, it must merely
//                   not hurt)
//          sample   lode::msg::SignalSample on TOPIC: XCDR2 encapsulation, truncated body,
//                   a sequence length of 2^31
//          info     lode::msg::SignalInfo on TOPIC (lode/signals): a boolean that is 2
// Waits (up to 30 s) for a reader to match, writes every case and waits until each reliable
// reader has acknowledged them. Exit 0: all written; 1: no reader or a write failed.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "lode/dds/participant.hpp"

namespace {

namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::InstanceHandle_t;
using eprosima::fastrtps::rtps::SerializedPayload_t;

/// A sample of the raw type: the bytes to put on the wire, encapsulation header included.
struct Raw {
  std::vector<std::uint8_t> bytes;
};

/// Claims a lodestone type name; writes whatever bytes it is given.
class RawType final : public fdds::TopicDataType {
 public:
  RawType(const std::string& name, bool keyed) {
    setName(name.c_str());
    m_typeSize = 4096;
    m_isGetKeyDefined = keyed;
  }
  bool serialize(void* data, SerializedPayload_t* payload) override {
    const auto& raw = static_cast<Raw*>(data)->bytes;
    if (raw.size() > payload->max_size) return false;
    std::memcpy(payload->data, raw.data(), raw.size());
    payload->length = static_cast<std::uint32_t>(raw.size());
    return true;
  }
  bool deserialize(SerializedPayload_t* /*payload*/, void* /*data*/) override { return false; }
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<Raw*>(data)->bytes.size()); };
  }
  void* createData() override { return new Raw(); }
  void deleteData(void* data) override { delete static_cast<Raw*>(data); }
  bool getKey(void* /*data*/, InstanceHandle_t* handle, bool /*force_md5*/) override {
    // One instance of our own: a key hash no pipeline's topic has.
    for (std::uint8_t i = 0; i < 16; ++i) handle->value[i] = static_cast<std::uint8_t>(0xA0 + i);
    return m_isGetKeyDefined;
  }
};

/// Little-endian plain CDR, aligned from the start of the body (after the 4-byte header).
class Cdr {
 public:
  explicit Cdr(std::uint8_t encapsulation_low) { bytes_ = {0x00, encapsulation_low, 0x00, 0x00}; }
  Cdr& u32(std::uint32_t v) { return align(4).put(&v, 4); }
  Cdr& u64(std::uint64_t v) { return align(8).put(&v, 8); }
  Cdr& f64(double v) { return align(8).put(&v, 8); }
  Cdr& u8(std::uint8_t v) { return put(&v, 1); }
  Cdr& str(const std::string& s, bool terminated = true) {
    u32(static_cast<std::uint32_t>(s.size() + (terminated ? 1 : 0)));
    put(s.data(), s.size());
    return terminated ? u8(0) : *this;
  }
  Cdr& cut(std::size_t body_bytes) {
    bytes_.resize(4 + body_bytes);
    return *this;
  }
  [[nodiscard]] Raw raw() const { return {bytes_}; }

 private:
  Cdr& align(std::size_t n) {
    while ((bytes_.size() - 4) % n != 0) bytes_.push_back(0);
    return *this;
  }
  Cdr& put(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    bytes_.insert(bytes_.end(), b, b + n);
    return *this;
  }
  std::vector<std::uint8_t> bytes_;
};

constexpr std::uint8_t kCdrLe = 0x01;
constexpr std::uint8_t kXcdr2Le = 0x07;  // what an XCDR2 writer (Cyclone DDS by default) sends
constexpr std::uint32_t kHuge = 0x80000000u;

Cdr command(std::uint8_t encapsulation, const std::string& kind) {
  Cdr c(encapsulation);
  c.str("malformed-sender").u64(7).str(kind).str("").str("").str("").str("");
  return c;
}

struct Case {
  const char* name;
  Raw raw;
};

std::vector<Case> cases(const std::string& layout) {
  if (layout == "command") {
    Cdr unterminated(kCdrLe);
    unterminated.str("malformed-sender", false).u64(8).str("status").str("").str("").str("").str("");
    return {{"xcdr2", command(kXcdr2Le, "status").raw()},
            {"truncated", command(kCdrLe, "status").cut(22).raw()},
            {"string of 2^31 bytes", Cdr(kCdrLe).u32(kHuge).str("x").raw()},
            {"string without terminator", unterminated.raw()}};
  }
  if (layout == "sample") {
    const auto sample = [](std::uint8_t encapsulation) {
      Cdr c(encapsulation);
      c.u64(1u << 30).u64(0).u64(0).u32(3).f64(1).f64(2).f64(3);
      return c;
    };
    Cdr huge(kCdrLe);
    huge.u64(1u << 30).u64(0).u64(0).u32(kHuge).f64(1).f64(2);
    return {{"xcdr2", sample(kXcdr2Le).raw()}, {"truncated", sample(kCdrLe).cut(12).raw()},
            {"sequence of 2^31 doubles", huge.raw()}};
  }
  if (layout == "info") {
    Cdr c(kCdrLe);
    c.u64(0xA0A1A2A3A4A5A6A7ull).str("lode/malformed/x/y").str("malformed").str("x").str("y");
    c.u32(0).u32(0).f64(1).f64(1).u32(1).str("signal").u32(0).u32(0).u32(0).u8(2);  // reliable = 2
    return {{"boolean 2", c.raw()}};
  }
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s DOMAIN command|sample|info TOPIC\n", argv[0]);
    return 2;
  }
  const std::string layout = argv[2], topic_name = argv[3];
  const std::vector<Case> to_send = cases(layout);
  if (to_send.empty()) {
    std::fprintf(stderr, "malformed_sender: unknown layout '%s'\n", layout.c_str());
    return 2;
  }
  const char* type_name = layout == "command" ? "lode::msg::Command"
                          : layout == "sample" ? "lode::msg::SignalSample"
                                               : "lode::msg::SignalInfo";
  lode::dds::ParticipantOptions options;
  options.domain = std::atoi(argv[1]);
  options.name = "malformed-sender";
  auto created = lode::dds::create_participant(options);
  if (!created) {
    std::fprintf(stderr, "malformed_sender: %s\n", created.error().c_str());
    return 1;
  }
  fdds::DomainParticipant* participant = *created;
  fdds::TypeSupport type(new RawType(type_name, layout == "info"));
  type.register_type(participant);
  fdds::Topic* topic = participant->create_topic(topic_name, type_name, fdds::TOPIC_QOS_DEFAULT);
  fdds::Publisher* publisher = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  // lode/signals readers ask for transient-local; offering it satisfies volatile readers too.
  qos.durability().kind = fdds::TRANSIENT_LOCAL_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
  qos.endpoint().history_memory_policy = eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  fdds::DataWriter* writer = topic && publisher ? publisher->create_datawriter(topic, qos) : nullptr;
  int rc = 0;
  if (writer == nullptr) {
    std::fprintf(stderr, "malformed_sender: could not create a writer on %s\n", topic_name.c_str());
    rc = 1;
  }
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  fdds::PublicationMatchedStatus matched;
  while (rc == 0 && (writer->get_publication_matched_status(matched), matched.current_count == 0)) {
    if (std::chrono::steady_clock::now() > give_up) {
      std::fprintf(stderr, "malformed_sender: no reader matched %s within 30 s\n", topic_name.c_str());
      rc = 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  for (std::size_t i = 0; rc == 0 && i < to_send.size(); ++i) {
    Raw raw = to_send[i].raw;
    if (!writer->write(&raw)) {
      std::fprintf(stderr, "malformed_sender: writing '%s' failed\n", to_send[i].name);
      rc = 1;
      break;
    }
    std::printf("malformed_sender: wrote %s (%zu bytes) on %s\n", to_send[i].name, raw.bytes.size(), topic_name.c_str());
  }
  if (rc == 0 && writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(20, 0)) != ReturnCode_t::RETCODE_OK) {
    std::fprintf(stderr, "malformed_sender: the readers did not acknowledge within 20 s\n");
    rc = 1;
  }
  // Best-effort readers acknowledge nothing: give them a moment before the writer goes.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  participant->delete_contained_entities();
  lode::dds::delete_participant(participant);
  return rc;
}
