#include "memory_check.hpp"

#include <cstdio>
#include <filesystem>

#include "lode/host_memory.hpp"

namespace lode::cli {

std::uint64_t files_bytes(const std::vector<std::string>& paths) {
  std::uint64_t total = 0;
  for (const auto& path : paths) {
    std::error_code ec;
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (!ec) total += static_cast<std::uint64_t>(size);
  }
  return total;
}

bool enough_memory(const char* command, const std::string& what, std::uint64_t needed, const char* why) {
  const auto available = available_memory_bytes();
  if (!available || needed <= *available) return true;
  std::fprintf(stderr,
               "lode: %s: %s needs about %s of memory (%s); this process has %s left (available memory, within "
               "its control group's limit). Run it on a machine with more memory free\n",
               command, what.c_str(), format_bytes(needed).c_str(), why, format_bytes(*available).c_str());
  return false;
}

}  // namespace lode::cli
