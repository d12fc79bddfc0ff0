#include "fatal_signals.hpp"

#include <string.h>
#include <unistd.h>

namespace lode::detail {

void write_stderr(const char* text) noexcept {
  const ssize_t written = ::write(STDERR_FILENO, text, ::strlen(text));
  (void)written;  // nothing better to do when stderr is gone
}

const char* signal_name(int sig) noexcept {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGABRT: return "SIGABRT";
    default: return "a fatal signal";
  }
}

}  // namespace lode::detail
