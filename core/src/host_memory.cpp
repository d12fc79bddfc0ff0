#include "lode/host_memory.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace lode {
namespace {

std::optional<std::uint64_t> parse_unsigned(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

/// The figure after `key` and `separator` on a line of `text` ("MemAvailable:   1234 kB" with
/// ':', "inactive_file 4096" with ' '), without a " kB" after it.
std::optional<std::uint64_t> keyed_figure(std::string_view text, std::string_view key, char separator) {
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    std::string_view line = text.substr(at, end - at);
    at = end + 1;
    if (line.size() <= key.size() || line.substr(0, key.size()) != key || line[key.size()] != separator) continue;
    line.remove_prefix(key.size() + 1);
    if (line.size() >= 3 && line.substr(line.size() - 3) == " kB") line.remove_suffix(3);
    return parse_unsigned(line);
  }
  return std::nullopt;
}

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  if (!f) return {};
  std::ostringstream text;
  text << f.rdbuf();
  return text.str();
}

/// The headroom of this process's memory control group: cgroup v2 ("0::/path") or the v1
/// memory hierarchy ("N:memory:/path") of /proc/self/cgroup.
std::optional<std::uint64_t> own_cgroup_headroom() {
  std::istringstream lines(read_file("/proc/self/cgroup"));
  std::optional<std::uint64_t> headroom;
  for (std::string line; std::getline(lines, line);) {
    const auto first = line.find(':');
    const auto second = first == std::string::npos ? std::string::npos : line.find(':', first + 1);
    if (second == std::string::npos) continue;
    const std::string controllers = line.substr(first + 1, second - first - 1);
    const std::string path = line.substr(second + 1);
    std::optional<std::uint64_t> h;
    if (line.compare(0, first, "0") == 0 && controllers.empty()) {
      const std::string dir = "/sys/fs/cgroup" + path;
      h = cgroup_headroom_bytes(read_file(dir + "/memory.max"), read_file(dir + "/memory.current"),
                                read_file(dir + "/memory.stat"));
    } else if (controllers == "memory") {
      const std::string dir = "/sys/fs/cgroup/memory" + path;
      h = cgroup_headroom_bytes(read_file(dir + "/memory.limit_in_bytes"), read_file(dir + "/memory.usage_in_bytes"),
                                read_file(dir + "/memory.stat"));
    }
    if (h) headroom = headroom ? std::min(*headroom, *h) : *h;
  }
  return headroom;
}

}  // namespace

std::optional<std::uint64_t> meminfo_available_bytes(std::string_view meminfo) {
  const auto available = keyed_figure(meminfo, "MemAvailable", ':');
  if (!available) return std::nullopt;
  return (*available + keyed_figure(meminfo, "SwapFree", ':').value_or(0)) * 1024;
}

std::optional<std::uint64_t> cgroup_headroom_bytes(std::string_view limit, std::string_view usage,
                                                   std::string_view stat) {
  const auto l = parse_unsigned(limit);
  auto u = parse_unsigned(usage);
  // v2 writes "max" for no limit; v1 a page-rounded 2^63 - 1.
  if (!l || !u || *l >= (std::uint64_t{1} << 62)) return std::nullopt;
  // The usage counts the group's page cache, which the kernel writes back and drops before it
  // refuses memory: every file page, active or not, as MemAvailable counts all of the page
  // cache but a small reserve. A file the process has just written and read back (a replay's
  // own, 194 MB for a 5-minute recording) is active; counting only the inactive pages, a
  // replay under a 250 MiB limit was refused 17 MB to read one series with 15 MB "left".
  const auto figure = [&](const char* key, const char* total_key) {
    return keyed_figure(stat, key, ' ').value_or(keyed_figure(stat, total_key, ' ').value_or(0));
  };
  const std::uint64_t droppable =
      figure("inactive_file", "total_inactive_file") + figure("active_file", "total_active_file");
  *u -= std::min(*u, droppable);
  return *l > *u ? *l - *u : 0;
}

std::optional<std::uint64_t> available_memory_bytes() {
  std::optional<std::uint64_t> available = meminfo_available_bytes(read_file("/proc/meminfo"));
  if (const auto headroom = own_cgroup_headroom())
    available = available ? std::min(*available, *headroom) : *headroom;
  return available;
}

std::string format_bytes(std::uint64_t bytes) {
  char text[32];
  const double b = static_cast<double>(bytes);
  if (b >= 1e9) std::snprintf(text, sizeof text, "%.1f GB", b / 1e9);
  else if (b >= 1e6) std::snprintf(text, sizeof text, "%.0f MB", b / 1e6);
  else std::snprintf(text, sizeof text, "%.0f kB", b / 1e3);
  return text;
}

}  // namespace lode
