// Commands that hold whole recordings in memory (replay, plot) check first that they fit in
// the memory this process has left, and refuse at once with the figures when they do not,
// instead of running into std::bad_alloc or the OOM killer halfway.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace lode::cli {

/// The sizes of `paths` added up (a file that cannot be read counts 0: its reader reports it).
std::uint64_t files_bytes(const std::vector<std::string>& paths);

/// Whether `needed` bytes fit in what this process has left (lode::available_memory_bytes();
/// true when that cannot be read). If not, prints "lode: COMMAND: WHAT needs about N of memory
/// (WHY); this process has M left ..." and returns false.
bool enough_memory(const char* command, const std::string& what, std::uint64_t needed, const char* why);

}  // namespace lode::cli
