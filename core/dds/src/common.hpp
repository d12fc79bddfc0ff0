// What the bridge and the client agree on besides the IDL: topic names, type registration
// and the QoS of each topic (a reader only matches a writer whose QoS it accepts).
// Private to lodestone_dds.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/participant/ParticipantDiscoveryInfo.h>

#include "guarded_type.hpp"
#include "lode/sdk/status.hpp"
#include "lode_msgsPubSubTypes.h"

// Inlined (a header of Debian's libxxhash-dev): the key of lode/signals costs no library at
// run time.
#define XXH_INLINE_ALL
#include <xxhash.h>

namespace lode::dds::detail {

namespace fdds = eprosima::fastdds::dds;

inline constexpr const char* kSignalsTopic = "lode/signals";

/// Register every lodestone type with `participant` (idempotent), each Guarded: a sample
/// that does not decode is dropped and counted, never thrown.
inline Status register_types(fdds::DomainParticipant* participant) {
  const auto one = [&](fdds::TopicDataType* type) -> bool {
    fdds::TypeSupport support(type);
    if (participant->find_type(support.get_type_name()).get() != nullptr) return true;
    return support.register_type(participant) == ReturnCode_t::RETCODE_OK;
  };
  namespace m = lode::msg;
  if (!one(new Guarded<m::SignalInfoPubSubType>()) || !one(new Guarded<m::SignalSamplePubSubType>()) ||
      !one(new Guarded<m::StageStatePubSubType>()) || !one(new Guarded<m::TimingStatsPubSubType>()) ||
      !one(new Guarded<m::EventPubSubType>()) || !one(new Guarded<m::CommandPubSubType>()) ||
      !one(new Guarded<m::ReplyPubSubType>())) {
    return Status::error("could not register lodestone's DDS types with the participant");
  }
  return Status::ok();
}

/// How long a participant holds its reply to a participant it has just discovered.
/// Fast DDS 2.9 (RTPSParticipantImpl::enable) sends a new participant's first announcement
/// to every initial peer (64 ports on 127.0.0.1) and only then starts handing what its
/// sockets receive to the protocol. A running participant answers that announcement at once
/// with its own, within a millisecond, often while the newcomer is still sending: the answer
/// is dropped, the newcomer's later announcements get none (it is no longer new), and it
/// hears of the running participant only at its next periodic announcement, up to 1 s later
/// (half of all `lode echo` started beside a pipeline). Discovery listeners are called before
/// the answer is sent, on the receiving thread: holding there delays the answer until the
/// newcomer listens. 25 ms is many times the newcomer's announcement on a loaded host.
inline constexpr std::chrono::milliseconds kNewParticipantReplyHold{25};

/// Call from on_participant_discovery: holds the answer to a newly discovered participant.
inline void hold_reply_to_new_participant(const eprosima::fastrtps::rtps::ParticipantDiscoveryInfo& info) {
  if (info.status == eprosima::fastrtps::rtps::ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT)
    std::this_thread::sleep_for(kNewParticipantReplyHold);
}

/// SignalInfo's key: XXH64, seed 0, of the topic name's bytes. Eight bytes travel as
/// themselves in the DDSI key hash (a longer key travels as its MD5), so a reader of any
/// DDS implementation can map a dispose back to its instance.
inline std::uint64_t topic_id(const std::string& topic) { return XXH64(topic.data(), topic.size(), 0); }

inline const char* type_name_signal_info() { return "lode::msg::SignalInfo"; }
inline const char* type_name_signal_sample() { return "lode::msg::SignalSample"; }
inline const char* type_name_stage_state() { return "lode::msg::StageState"; }
inline const char* type_name_timing() { return "lode::msg::TimingStats"; }
inline const char* type_name_event() { return "lode::msg::Event"; }
inline const char* type_name_command() { return "lode::msg::Command"; }
inline const char* type_name_reply() { return "lode::msg::Reply"; }

/// Malformed samples of every lodestone type dropped by the readers of `participant`.
inline std::uint64_t malformed_samples(fdds::DomainParticipant* participant) {
  std::uint64_t total = 0;
  for (const char* type : {type_name_signal_info(), type_name_signal_sample(), type_name_stage_state(),
                           type_name_timing(), type_name_event(), type_name_command(), type_name_reply()}) {
    total += malformed_samples(participant, type);
  }
  return total;
}

enum class Durability { volatile_, transient_local };

/// KEEP_LAST `depth` per instance with resource limits that admit it (Fast DDS's defaults
/// cap an instance at 400 samples and a topic at 10 instances).
template <typename Qos>
void keep_last(Qos& qos, std::int32_t depth, std::int32_t instances = 1) {
  depth = std::max(depth, 1);
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = depth;
  qos.resource_limits().max_instances = instances;
  qos.resource_limits().max_samples_per_instance = depth;
  qos.resource_limits().max_samples = depth * instances;
  qos.resource_limits().allocated_samples = std::min(depth * instances, 64);
}

inline fdds::DataWriterQos writer_qos(Durability durability, std::int32_t depth,
                                      std::int32_t instances = 1) {
  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  // A stalled or vanished reader must never hold the publisher thread: a full history
  // drops its oldest sample (KEEP_LAST), and a write that still cannot proceed fails
  // after 1 ms and is counted.
  qos.reliability().max_blocking_time = eprosima::fastrtps::Duration_t(0, 1000000);
  // A late joiner's reader often matches the writer after the writer has sent it the
  // history and its first HEARTBEAT, which it then ignores; the next HEARTBEAT (Fast DDS:
  // every 3 s) is what gets it the metadata and events. Every 50 ms a client has them at
  // once; heartbeats only go out while a reader has something unacknowledged.
  qos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0, 50'000'000);
  qos.durability().kind = durability == Durability::transient_local
                              ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS
                              : fdds::VOLATILE_DURABILITY_QOS;
  qos.publish_mode().kind = fdds::SYNCHRONOUS_PUBLISH_MODE;
  // Sequences are unbounded in the IDL: payloads are sized per sample.
  qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  keep_last(qos, depth, instances);
  return qos;
}

/// Signal/state topics: the reliability the pipeline chose (telemetry.reliability).
template <typename Qos>
Qos with_reliability(Qos qos, bool reliable) {
  qos.reliability().kind = reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS;
  return qos;
}

inline fdds::DataReaderQos reader_qos(Durability durability, std::int32_t depth,
                                      std::int32_t instances = 1) {
  fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  // A new reader asks a matched writer for what it holds after this delay (Fast DDS: 70 ms),
  // which is most of the time a late joiner waits for the metadata once matched (tries
  // instrumented under strace: 61 to 66 ms from match to metadata, 12 to 18 ms in the rest).
  qos.reliable_reader_qos().times.initialAcknackDelay = eprosima::fastrtps::Duration_t(0, 5'000'000);
  qos.durability().kind = durability == Durability::transient_local
                              ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS
                              : fdds::VOLATILE_DURABILITY_QOS;
  qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  keep_last(qos, depth, instances);
  return qos;
}

/// Depth that holds one second of samples at `rate_hz` (at least `minimum`).
inline std::int32_t one_second(double rate_hz, std::int32_t minimum) {
  const double n = rate_hz > 0 ? rate_hz : 0.0;
  return std::max(minimum, static_cast<std::int32_t>(std::min(n, 1e6)));
}

// Per-topic QoS both sides use.
inline constexpr std::int32_t kSignalInfoInstances = 4096;  ///< topics across all pipelines
inline constexpr std::int32_t kEventsDepth = 100;
inline constexpr std::int32_t kTimingDepth = 16;
/// Replies kept for readers that match late (transient local): every new client receives
/// them once, so enough for a burst in flight, not a history.
inline constexpr std::int32_t kReplyDepth = 256;
/// Commands in flight that the pipeline's reader holds before it pushes back on the writers.
inline constexpr std::int32_t kCommandQueue = 1024;

/// Commands are never overwritten: the reader keeps all of them (up to kCommandQueue, then
/// the reliable protocol holds the rest at the writer), and the writer keeps all it has not
/// had acknowledged, blocking write() for up to `blocking_s` when the reader is full, so a
/// burst is either delivered whole or refused to the sender, never thinned out in silence.
template <typename Qos>
Qos keep_all_commands(Qos qos, double blocking_s) {
  qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
  qos.resource_limits().max_instances = 1;
  qos.resource_limits().max_samples_per_instance = kCommandQueue;
  qos.resource_limits().max_samples = kCommandQueue;
  qos.resource_limits().allocated_samples = 64;
  qos.reliability().max_blocking_time = eprosima::fastrtps::Duration_t(blocking_s);
  return qos;
}

}  // namespace lode::dds::detail
