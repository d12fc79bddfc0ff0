#include "shared_memory_leftovers.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <ctime>
#include <mutex>
#include <string_view>
#include <vector>

namespace lode::dds::detail {
namespace {

enum class Leftover { none, segment, port };

/// What a lock file's name says it guards: "fastrtps_<16 of [0-9a-z]>_el|_sl" a segment,
/// "fastrtps_port<digits>_el|_sl" a port.
Leftover kind_of_lock(std::string_view name) {
  constexpr std::string_view kPrefix = "fastrtps_", kPort = "port";
  if (name.size() < kPrefix.size() + 3 || name.substr(0, kPrefix.size()) != kPrefix) return Leftover::none;
  const std::string_view suffix = name.substr(name.size() - 3);
  if (suffix != "_el" && suffix != "_sl") return Leftover::none;
  std::string_view id = name.substr(kPrefix.size(), name.size() - kPrefix.size() - 3);
  const bool is_port = id.size() > kPort.size() && id.substr(0, kPort.size()) == kPort;
  if (is_port) {
    id.remove_prefix(kPort.size());
    return std::all_of(id.begin(), id.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })
               ? Leftover::port
               : Leftover::none;
  }
  const bool segment_id = id.size() == 16 && std::all_of(id.begin(), id.end(), [](char c) {
                            return std::isdigit(static_cast<unsigned char>(c)) || (c >= 'a' && c <= 'z');
                          });
  return segment_id ? Leftover::segment : Leftover::none;
}

/// The memory a file holds (tmpfs: its allocated blocks), 0 when it is not there.
std::uint64_t held_bytes(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return 0;
  return static_cast<std::uint64_t>(st.st_blocks) * 512;
}

}  // namespace

RemovedLeftovers remove_dead_shared_memory(const std::string& directory, std::chrono::seconds min_age) {
  RemovedLeftovers removed;
  std::vector<std::string> names;
  if (DIR* dir = ::opendir(directory.c_str())) {
    while (const dirent* entry = ::readdir(dir)) names.emplace_back(entry->d_name);
    ::closedir(dir);
  }
  const uid_t uid = ::getuid();
  const std::time_t now = std::time(nullptr);
  for (const std::string& name : names) {
    const Leftover kind = kind_of_lock(name);
    if (kind == Leftover::none) continue;
    const std::string lock = directory + "/" + name;
    const int fd = ::open(lock.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
    if (fd < 0) continue;
    struct stat st {};
    const bool candidate = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_uid == uid &&
                           now - st.st_mtime >= min_age.count();
    // Locked: its owner lives (or another process is judging it right now). Ours, it stays
    // locked while the files go, so no other cleaner acts on them at the same time.
    if (!candidate || ::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd);
      continue;
    }
    const std::string guarded = directory + "/" + name.substr(0, name.size() - 3);
    std::vector<std::string> files{guarded};
    if (kind == Leftover::port) files.push_back(directory + "/sem." + name.substr(0, name.size() - 3) + "_mutex");
    files.push_back(lock);  // last: while it is there, the others are known to be leftovers
    std::uint64_t bytes = 0;
    for (const auto& file : files) {
      const std::uint64_t size = held_bytes(file);
      if (::unlink(file.c_str()) == 0) bytes += size;
    }
    ::close(fd);
    removed.bytes += bytes;
    if (kind == Leftover::segment) ++removed.segments;
    else ++removed.ports;
  }
  return removed;
}

void remove_dead_shared_memory_once() {
  static std::once_flag once;
  std::call_once(once, [] { (void)remove_dead_shared_memory("/dev/shm", std::chrono::seconds(2)); });
}

}  // namespace lode::dds::detail
