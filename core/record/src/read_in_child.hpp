// A damaged recording must give an error, not a crash. HDF5 1.10 (Debian 12's) trusts the
// sizes a file states: a variable-length string is copied out of the file's global heap with
// the length the heap claims (H5HG_read), so one flipped byte there takes the reading process
// down with SIGSEGV. The library cannot be made to check that, so a file is read whole once in
// a child process before this process reads any of it: if the child dies, the file is refused
// with the reason, and this process never touches it.
#pragma once

#include <sys/stat.h>

#include <string>

#include "lode/sdk/status.hpp"

namespace lode::record::detail {

/// A file's identity and version from its stat: device, inode, size and modification time.
/// Equal for the same file unchanged; a file rewritten in between gets another.
std::string file_identity(const struct stat& st);

/// Reads every part of the recording at `path` that a reader may touch; the first error, as a
/// reader reports it after "recording '<path>': ". Runs in the child.
using ReadWhole = Status (*)(const std::string& path);

/// Ok when `path` was read whole by `read_whole` in a child process (or when this process has
/// already checked or written the same file: same device, inode, size and modification
/// time). Otherwise the reason, to follow "recording '<path>': ": the error the child met
/// (the file is then never read here: a damaged length can make HDF5 allocate and clear
/// gigabytes before it fails), or that the child crashed, ran out of its memory allowance or
/// stopped making progress (no note_progress() for 20 s: a damaged file can send HDF5 round
/// a loop for ever). Inside the child it returns ok at once. A file that cannot be stat'ed
/// is left to the reader's own error.
Status read_first_in_child(const std::string& path, ReadWhole read_whole);

/// In the child: a part of the file has been read (the parent stops a child that goes
/// without one for 20 s). Does nothing elsewhere.
void note_progress();

/// A file this process has just written and closed: read without a child.
void trust_written_file(const std::string& path);

}  // namespace lode::record::detail
