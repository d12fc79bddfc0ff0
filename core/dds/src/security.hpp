// DDS Security for lodestone participants: the Fast DDS 2.9 builtin plugins (PKI-DH
// authentication, Access-Permissions access control, AES-GCM-GMAC cryptography) configured
// from the YAML `telemetry.security` section. tools/dds-security/ makes a lab PKI for it.
#pragma once

#include "lode/sdk/status.hpp"
#include "lode/telemetry.hpp"

namespace eprosima::fastdds::dds {
class DomainParticipantQos;
}  // namespace eprosima::fastdds::dds

namespace lode::dds {

/// Add the `dds.sec.*` properties of `spec` to `qos` (replacing earlier values of the same
/// properties). Every file is checked first: it must exist, be readable and look like what the
/// field names (PEM certificate, PEM private key, S/MIME signed document), so a wrong path
/// fails here with the field's name instead of as a bare participant-creation failure inside
/// Fast DDS. Relative paths are taken relative to the working directory (the YAML loader
/// resolves them against the pipeline file before this is called).
///
/// A spec whose fields are all empty is a no-op (security off). A spec with some fields but no
/// `certificate` is an error, so a typo never silently turns security off.
/// Example error: "telemetry.security.private_key: cannot read /x/y.pem (No such file or directory)".
[[nodiscard]] Status apply_security(const SecuritySpec& spec, eprosima::fastdds::dds::DomainParticipantQos& qos);

}  // namespace lode::dds
