#include "security.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>

namespace lode::dds {
namespace {

// Property names and values of the Fast DDS 2.9 builtin security plugins.
constexpr const char* kAuthPlugin = "dds.sec.auth.plugin";
constexpr const char* kAuthPkiDh = "builtin.PKI-DH";
constexpr const char* kAuthPrefix = "dds.sec.auth.builtin.PKI-DH.";
constexpr const char* kAccessPlugin = "dds.sec.access.plugin";
constexpr const char* kAccessPermissions = "builtin.Access-Permissions";
constexpr const char* kAccessPrefix = "dds.sec.access.builtin.Access-Permissions.";
constexpr const char* kCryptoPlugin = "dds.sec.crypto.plugin";
constexpr const char* kCryptoAesGcmGmac = "builtin.AES-GCM-GMAC";

// What a file must contain; checked on its first bytes so that swapped or unsigned files are
// reported by field name here (Fast DDS only logs a line and refuses the participant).
enum class Content { certificate, private_key, signed_document };

struct FileField {
  const char* field;  // YAML key under telemetry.security
  const std::string* path;
  Content content;
  const char* property_prefix;  // plugin that reads the file
  const char* property;
};

std::string field_error(const char* field, const std::string& what) {
  return std::string("telemetry.security.") + field + ": " + what;
}

bool contains(std::string_view text, std::string_view needle) { return text.find(needle) != std::string_view::npos; }

Status check_content(const FileField& file, std::string_view head) {
  switch (file.content) {
    case Content::certificate:
      if (!contains(head, "-----BEGIN CERTIFICATE-----")) {
        return Status::error(field_error(file.field, *file.path + " is not a PEM certificate"));
      }
      break;
    case Content::private_key:
      if (!contains(head, "PRIVATE KEY-----")) {
        return Status::error(field_error(file.field, *file.path + " is not a PEM private key"));
      }
      break;
    case Content::signed_document:
      // `openssl smime -sign` writes application/x-pkcs7-signature, newer tools pkcs7-signature.
      if (!contains(head, "pkcs7-signature")) {
        return Status::error(field_error(
            file.field, *file.path +
                            " is not an S/MIME signed document (sign the XML with `openssl smime -sign -text`, "
                            "see tools/dds-security/README.md)"));
      }
      break;
  }
  return Status::ok();
}

// The file's absolute path as a file:// URI, or why it cannot be used.
Expected<std::string> readable_file_uri(const FileField& file) {
  const std::string& path = *file.path;
  const auto cannot_read = [&](int error) {
    return Status::error(
        field_error(file.field, "cannot read " + path + " (" + std::generic_category().message(error) + ")"));
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return cannot_read(errno);
  }
  struct stat info {};
  if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
    ::close(fd);
    return Status::error(field_error(file.field, "cannot read " + path + " (not a regular file)"));
  }
  // The headers sit at the start of every PEM and S/MIME file.
  std::array<char, 4096> buffer{};
  const ssize_t got = ::read(fd, buffer.data(), buffer.size());
  const int read_error = errno;
  ::close(fd);
  if (got < 0) {
    return cannot_read(read_error);
  }
  if (Status content = check_content(file, std::string_view(buffer.data(), static_cast<std::size_t>(got)));
      !content) {
    return content;
  }
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  if (ec) {
    return Status::error(field_error(file.field, "cannot resolve " + path + " (" + ec.message() + ")"));
  }
  return "file://" + absolute.lexically_normal().string();
}

void set_property(eprosima::fastdds::dds::DomainParticipantQos& qos, const std::string& name,
                  const std::string& value) {
  auto& properties = qos.properties().properties();
  for (auto& property : properties) {
    if (property.name() == name) {
      property.value(value);
      return;
    }
  }
  properties.emplace_back(name, value);
}

}  // namespace

Status apply_security(const SecuritySpec& spec, eprosima::fastdds::dds::DomainParticipantQos& qos) {
  const std::string& permissions_ca = spec.permissions_ca.empty() ? spec.ca_certificate : spec.permissions_ca;
  const std::array<FileField, 6> files{{
      {"ca_certificate", &spec.ca_certificate, Content::certificate, kAuthPrefix, "identity_ca"},
      {"certificate", &spec.certificate, Content::certificate, kAuthPrefix, "identity_certificate"},
      {"private_key", &spec.private_key, Content::private_key, kAuthPrefix, "private_key"},
      {spec.permissions_ca.empty() ? "ca_certificate" : "permissions_ca", &permissions_ca, Content::certificate,
       kAccessPrefix, "permissions_ca"},
      {"governance", &spec.governance, Content::signed_document, kAccessPrefix, "governance"},
      {"permissions", &spec.permissions, Content::signed_document, kAccessPrefix, "permissions"},
  }};

  if (!spec.enabled()) {
    for (const FileField& file : files) {
      if (!file.path->empty()) {
        return Status::error(field_error(
            "certificate", std::string("missing, but telemetry.security.") + file.field +
                               " is set (give every file, or remove telemetry.security to run without security)"));
      }
    }
    return Status::ok();
  }

  // Check everything before touching the QoS, so a failed call leaves it unchanged.
  std::vector<std::pair<std::string, std::string>> properties;
  for (const FileField& file : files) {
    if (file.path->empty()) {
      return Status::error(field_error(file.field, "required when telemetry.security is given"));
    }
    Expected<std::string> uri = readable_file_uri(file);
    if (!uri) {
      return uri.status();
    }
    properties.emplace_back(std::string(file.property_prefix) + file.property, std::move(*uri));
  }

  set_property(qos, kAuthPlugin, kAuthPkiDh);
  set_property(qos, kAccessPlugin, kAccessPermissions);
  set_property(qos, kCryptoPlugin, kCryptoAesGcmGmac);
  for (const auto& [name, value] : properties) {
    set_property(qos, name, value);
  }
  return Status::ok();
}

}  // namespace lode::dds
