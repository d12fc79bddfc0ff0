// Reading a configuration file that may be hostile or simply wrong.
//
// A pipeline file is small text a person wrote. Anything else handed to the loader (a device
// such as /dev/zero, a FIFO nobody writes to, a multi-megabyte generated file) is refused
// before it is read, with a message naming the file, so no `lode` command can be made to hang
// or to run out of memory by the file it is given.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "lode/sdk/diagnostics.hpp"

namespace lode {

/// Largest configuration file read (1 MiB). The shipped pipelines are under 10 KiB; a file
/// far above that is almost certainly not a pipeline, and yaml-cpp keeps about 60 bytes per
/// parsed character, so this also caps the parser's memory at some tens of megabytes.
inline constexpr std::size_t kMaxConfigFileBytes = std::size_t{1} << 20;

/// The whole text of `path`, or nullopt with a diagnostic naming the file when it is not a
/// regular file (directory, FIFO, device, socket), cannot be opened, or is larger than
/// `max_bytes`. Never blocks on a FIFO and never reads more than `max_bytes` + 1 bytes.
std::optional<std::string> read_config_file(const std::string& path, Diagnostics& diagnostics,
                                            std::size_t max_bytes = kMaxConfigFileBytes);

}  // namespace lode
