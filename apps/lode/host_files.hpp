// The files `lode rtcheck` reads to judge a host (/sys, /proc, /etc, /dev), all through one
// root directory: the command reads "/", the unit tests a fake tree in a temporary folder.
// Every read may fail (containers and VMs lack much of /sys); the callers say "unknown" then.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace lode::cli {

class HostFiles {
 public:
  explicit HostFiles(std::string root);

  /// The file's text without trailing blanks and newlines; nullopt when it cannot be read.
  [[nodiscard]] std::optional<std::string> read(const std::string& path) const;
  /// Names in a directory, sorted; empty when it cannot be listed.
  [[nodiscard]] std::vector<std::string> list(const std::string& dir) const;
  [[nodiscard]] bool exists(const std::string& path) const;
  /// Whether this process may open the file for writing (access(W_OK)).
  [[nodiscard]] bool writable(const std::string& path) const;

 private:
  [[nodiscard]] std::string full(const std::string& path) const;
  std::string root_;
};

/// The kernel's CPU list format ("0-3,6"); nullopt when malformed.
std::optional<std::set<int>> parse_cpu_list(const std::string& text);
/// "0-3,6" from a set, the kernel's own format, for fix commands.
std::string format_cpu_list(const std::set<int>& cpus);
/// The kernel's hexadecimal CPU mask ("ff,00000003", /proc/irq/default_smp_affinity).
std::optional<std::set<int>> parse_cpu_mask(const std::string& text);
std::string format_cpu_mask(const std::set<int>& cpus);

/// What the kernel says about this process (/proc/self/status, /proc/self/limits: the same
/// numbers getuid, getgroups, capget and getrlimit return, read as files so tests fake them).
struct ProcessFacts {
  bool known = false;  ///< /proc/self/status was readable
  std::uint32_t uid = 0;
  std::vector<std::uint32_t> groups;
  std::uint64_t effective_caps = 0;
  bool limits_known = false;  ///< /proc/self/limits was readable
  std::optional<std::uint64_t> rtprio_limit;   ///< soft RLIMIT_RTPRIO
  std::optional<std::uint64_t> memlock_limit;  ///< soft RLIMIT_MEMLOCK in bytes; nullopt = unlimited
  [[nodiscard]] bool has_cap(int cap) const { return (effective_caps >> cap) & 1U; }
};
ProcessFacts read_process_facts(const HostFiles& files);

}  // namespace lode::cli
