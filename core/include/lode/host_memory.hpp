// How much memory this process may still take: what the kernel reports as available, capped
// by the memory limit of the process's control group (a systemd service's MemoryMax=, a
// container's limit). For commands that hold a whole recording in memory, so that one too
// large for the machine is refused with the figures instead of ending in the OOM killer.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace lode {

/// MemAvailable plus SwapFree of a /proc/meminfo text, in bytes; nullopt without MemAvailable.
std::optional<std::uint64_t> meminfo_available_bytes(std::string_view meminfo);

/// What a control group's processes may still take, in bytes: its limit less its usage, the
/// page cache it could drop (inactive_file and active_file of its memory.stat; v1:
/// total_inactive_file, total_active_file) not counted as used. From cgroup v2's memory.max, memory.current and memory.stat, or v1's
/// memory.limit_in_bytes, memory.usage_in_bytes and memory.stat; nullopt when there is no
/// limit ("max", or v1's near 2^63) or the limit or usage does not parse.
std::optional<std::uint64_t> cgroup_headroom_bytes(std::string_view limit, std::string_view usage,
                                                   std::string_view stat);

/// The memory this process may still take: /proc/meminfo's MemAvailable + SwapFree, capped by
/// the headroom of its memory control group (v2 or v1) where it has a limit; nullopt when
/// none of it can be read (then callers do not refuse anything).
std::optional<std::uint64_t> available_memory_bytes();

/// "387 MB", "1.2 GB": sizes as a person reads them in a message.
std::string format_bytes(std::uint64_t bytes);

}  // namespace lode
