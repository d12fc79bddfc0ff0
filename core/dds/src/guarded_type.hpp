// Anyone on the domain can write any bytes under a lodestone topic and type name. The
// type support fastddsgen generates lets every decoding error but a short buffer escape as
// an exception (an unknown encapsulation, a boolean that is neither 0 nor 1), and an
// exception thrown on a Fast DDS thread ends the process: one bad sample would stop a
// levitating stage's pipeline or a client. Guarded<> decodes with the generated code,
// turns every such error into "not deserialized", which makes Fast DDS drop the sample
// (take() skips it), and counts it so the drop is never silent.
// Private to lodestone_dds.
#pragma once

#include <atomic>
#include <cstdint>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

namespace lode::dds::detail {

/// Samples of one registered type that could not be decoded and were dropped.
class MalformedCount {
 public:
  [[nodiscard]] std::uint64_t malformed() const { return malformed_.load(std::memory_order_relaxed); }

 protected:
  void count_malformed() { malformed_.fetch_add(1, std::memory_order_relaxed); }
  void uncount_malformed() { malformed_.fetch_sub(1, std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> malformed_{0};
};

/// `Generated`: a fastddsgen PubSubType. Only decoding sees foreign bytes: serialize() and
/// getKey() work on samples this process built or decoded, so they cannot throw on them.
template <typename Generated>
class Guarded final : public Generated, public MalformedCount {
 public:
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    bool decoded = false;
    try {
      decoded = Generated::deserialize(payload, data);
    } catch (...) {  // whatever the decoder throws, it must not reach a Fast DDS thread
      decoded = false;
    }
    undecoded_ = decoded ? nullptr : data;
    if (!decoded) count_malformed();
    return decoded;
  }

  // A keyed sample whose writer sent no key hash is decoded twice: on receipt into a scratch
  // object, only to hash its key (Fast DDS ignores the result and asks for the key right
  // away), and again when it is taken, which drops it. Only the drop counts.
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool force_md5) override {
    if (data != nullptr && data == undecoded_) uncount_malformed();
    undecoded_ = nullptr;
    return Generated::getKey(data, handle, force_md5);
  }

 private:
  /// The object this thread last failed to decode into (Fast DDS calls getKey on the thread
  /// that decoded).
  static inline thread_local const void* undecoded_ = nullptr;
};

/// Malformed samples of `type_name` dropped by the readers of `participant` (0 when the type
/// is not registered there).
inline std::uint64_t malformed_samples(eprosima::fastdds::dds::DomainParticipant* participant,
                                       const char* type_name) {
  const eprosima::fastdds::dds::TypeSupport type = participant->find_type(type_name);
  const auto* count = dynamic_cast<const MalformedCount*>(type.get());
  return count != nullptr ? count->malformed() : 0;
}

}  // namespace lode::dds::detail
