// Internal: what the process's handlers of fatal signals share (the crash guard of a running
// pipeline, the guard around a plugin's load). Everything here is async-signal-safe.
#pragma once

#include <signal.h>

#include <cstddef>

namespace lode::detail {

/// The signals of a process dying of a bug: a bad pointer, a division by zero, an illegal
/// instruction, std::terminate.
inline constexpr int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
inline constexpr std::size_t kFatalSignalCount = sizeof kFatalSignals / sizeof kFatalSignals[0];

/// write(2) of `text` to stderr; nothing when stderr is gone.
void write_stderr(const char* text) noexcept;

/// "SIGSEGV", ... for the signals above; "a fatal signal" for any other.
const char* signal_name(int sig) noexcept;

}  // namespace lode::detail
