#include "lode/crash_guard.hpp"

#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>

#include "fatal_signals.hpp"
#include "lode/pipeline.hpp"

namespace lode {

namespace {

using detail::kFatalSignals;
using detail::signal_name;
using detail::write_stderr;

constexpr std::size_t kAlternateStackBytes = 64 * 1024;  // the handler needs little; overflow margin

std::atomic<Pipeline*> g_pipeline{nullptr};
std::atomic<int> g_handled{0};
// "<2>" when stderr is the journal's stream (systemd: $JOURNAL_STREAM is its device:inode), so
// the journal files the line as critical; decided when the guard is armed, not in the handler.
char g_journal_prefix[4] = "";
struct sigaction g_previous[detail::kFatalSignalCount];
bool g_installed = false;

// The decimal digits of `value` into `out` (at least 21 bytes); async-signal-safe.
const char* decimal(long value, char* out) noexcept {
  char digits[21];
  int n = 0;
  unsigned long v = value < 0 ? 0UL - static_cast<unsigned long>(value) : static_cast<unsigned long>(value);
  do {
    digits[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0 && n < 20);
  int i = 0;
  if (value < 0) out[i++] = '-';
  while (n > 0) out[i++] = digits[--n];
  out[i] = '\0';
  return out;
}

bool stderr_is_journal() {
  const char* env = getenv("JOURNAL_STREAM");
  unsigned long long device = 0, inode = 0;
  struct stat st{};
  return env != nullptr && sscanf(env, "%llu:%llu", &device, &inode) == 2 && fstat(STDERR_FILENO, &st) == 0 &&
         static_cast<unsigned long long>(st.st_dev) == device && static_cast<unsigned long long>(st.st_ino) == inode;
}

extern "C" void on_fatal_signal(int sig, siginfo_t* info, void* /*context*/) {
  // Only the first fatal signal drives the outputs: a second fault inside drive_safe() (or on
  // another thread meanwhile) must not loop. SA_RESETHAND has already restored the default
  // action, so returning (SIGSEGV re-faults) or the raise() below ends the process.
  if (g_handled.fetch_add(1) == 0) {
    if (Pipeline* p = g_pipeline.load()) {
      p->drive_safe();
      write_stderr(g_journal_prefix);
      write_stderr("lode: ");
      write_stderr(signal_name(sig));
      if (info != nullptr && info->si_code == SI_USER && info->si_pid != getpid()) {
        // kill(2) from outside, e.g. systemd's WatchdogSignal: not a bug in this process.
        char pid[24];
        write_stderr(": sent by process ");
        write_stderr(decimal(info->si_pid, pid));
        write_stderr(" (a service manager's watchdog, or kill); outputs driven to their safe values\n");
      } else {
        write_stderr(": the process is dying of a bug; outputs driven to their safe values\n");
      }
    }
  }
  raise(sig);  // blocked until the handler returns, then the default action
}

}  // namespace

CrashGuard::CrashGuard(Pipeline& pipeline) {
  if (!g_installed) {
    // An alternate stack, so a stack overflow (SIGSEGV on a full stack) still runs the handler.
    static char alternate_stack[kAlternateStackBytes];
    stack_t ss{};
    ss.ss_sp = alternate_stack;
    ss.ss_size = sizeof alternate_stack;
    (void)sigaltstack(&ss, nullptr);  // this thread's; elsewhere the handler uses the thread's stack
    for (std::size_t i = 0; i < detail::kFatalSignalCount; ++i) {
      struct sigaction sa{};
      sa.sa_sigaction = on_fatal_signal;
      sa.sa_flags = SA_SIGINFO | SA_RESETHAND | SA_ONSTACK;
      sigemptyset(&sa.sa_mask);
      (void)sigaction(kFatalSignals[i], &sa, &g_previous[i]);
    }
    g_installed = true;
  }
  if (stderr_is_journal()) memcpy(g_journal_prefix, "<2>", 4);
  g_pipeline.store(&pipeline);
}

CrashGuard::~CrashGuard() {
  g_pipeline.store(nullptr);
  if (g_installed) {
    for (std::size_t i = 0; i < detail::kFatalSignalCount; ++i)
      (void)sigaction(kFatalSignals[i], &g_previous[i], nullptr);
    g_installed = false;
  }
}

AlternateSignalStack::AlternateSignalStack() : stack_(new char[kAlternateStackBytes]) {
  stack_t ss{};
  ss.ss_sp = stack_.get();
  ss.ss_size = kAlternateStackBytes;
  installed_ = sigaltstack(&ss, nullptr) == 0;
}

AlternateSignalStack::~AlternateSignalStack() {
  if (!installed_) return;
  stack_t off{};
  off.ss_flags = SS_DISABLE;
  (void)sigaltstack(&off, nullptr);  // before the memory goes
}

}  // namespace lode
