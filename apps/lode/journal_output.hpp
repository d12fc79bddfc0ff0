// Where `lode run` writes its lines. Under systemd, stdout and stderr are the journal's
// stream socket, and the journal reads a leading "<N>" on a line as its syslog priority
// (sd-daemon's SyslogLevelPrefix): a fault is then an error in `journalctl -p err`, not an
// info line among thousands. $JOURNAL_STREAM names the socket's "DEVICE:INODE"; a stream
// that matches it gets the prefix on every line, one write(2) per line, so the lines of
// stdout and stderr (one socket) never interleave mid-line. A stream that does not match
// (a terminal, a file, a pipe; or a redirected stream under systemd) is written to as it
// always was: the output is byte for byte unchanged.
#pragma once

#include <cstdio>

namespace lode::cli {

/// syslog priorities, as the journal reads them from the "<N>" prefix.
enum class Severity : int { error = 3, warning = 4, notice = 5, info = 6, debug = 7 };

/// True when `fd` is the stream the journal reads ($JOURNAL_STREAM is its device:inode).
[[nodiscard]] bool is_journal_stream(int fd);

/// `base` (stdout or stderr) itself when it is not the journal; otherwise a stream that writes
/// each line to it with the "<N>" prefix of `severity`. Non-RT only (it locks).
[[nodiscard]] std::FILE* severity_stream(std::FILE* base, Severity severity);

/// fprintf to severity_stream(base, severity).
__attribute__((format(printf, 3, 4))) void say(std::FILE* base, Severity severity, const char* format, ...);

}  // namespace lode::cli
