// Creating Fast DDS 2.9 participants with lodestone's transport and security settings.
// Only this library includes Fast DDS headers; the core and the plugins never do.
#pragma once

#include <optional>
#include <string>

#include "lode/sdk/status.hpp"
#include "lode/telemetry.hpp"

namespace eprosima::fastdds::dds {
class DomainParticipant;
class DomainParticipantQos;
class DomainParticipantListener;
}  // namespace eprosima::fastdds::dds

namespace lode::dds {

struct ParticipantOptions {
  int domain = 0;
  std::string name;  ///< participant name (what `allow_participants` matches)
  TransportSpec transport;
  SecuritySpec security;
  /// A command-line client (lode echo, record, scope...), not a pipeline's bridge: with the
  /// loopback transport its readers listen on UDP by default, and on shared memory only where
  /// the pipeline can write into it (another user's pipeline cannot; see local_delivery.hpp).
  bool client = false;
};

/// Fill `qos` with the transports (and security properties) of `options`. Errors (bad
/// address, unreadable certificate) come back as values naming the field.
Status configure_participant_qos(const ParticipantOptions& options,
                                 eprosima::fastdds::dds::DomainParticipantQos& qos);

/// The participant name of `lode run`'s bridge: "lode-run/<pipeline>@<host>". Discovery
/// announces it before any topic matches, so a client learns which pipelines are live from
/// the participants it has discovered, well before their topics' data arrive.
std::string pipeline_participant_name(const std::string& pipeline, const std::string& host);
/// The pipeline of a participant named by pipeline_participant_name(), else nullopt.
std::optional<std::string> pipeline_of_participant(const std::string& participant_name);

/// Create a participant (the caller deletes it with delete_participant()). `listener`, when
/// given, hears participant discovery from creation on.
Expected<eprosima::fastdds::dds::DomainParticipant*> create_participant(
    const ParticipantOptions& options, eprosima::fastdds::dds::DomainParticipantListener* listener = nullptr);
void delete_participant(eprosima::fastdds::dds::DomainParticipant* participant);

/// Read defaults for command-line clients: LODE_DDS_DOMAIN, LODE_DDS_TRANSPORT
/// (loopback|shm|udp_loopback|network), LODE_DDS_PEERS (comma separated),
/// LODE_DDS_INTERFACES (comma separated).
ParticipantOptions options_from_environment(const std::string& name);
/// LODE_DDS_DOMAIN: nullopt when unset or empty, -1 when it is not an int (the caller names
/// the problem), else its value (not yet checked against 0..232).
std::optional<int> domain_from_environment();

}  // namespace lode::dds
