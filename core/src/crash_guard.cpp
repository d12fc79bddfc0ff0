#include "lode/crash_guard.hpp"

#include <signal.h>
#include <string.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>

#include "lode/pipeline.hpp"

namespace lode {

namespace {

constexpr int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
constexpr std::size_t kAlternateStackBytes = 64 * 1024;  // the handler needs little; overflow margin

std::atomic<Pipeline*> g_pipeline{nullptr};
std::atomic<int> g_handled{0};
struct sigaction g_previous[sizeof kFatalSignals / sizeof kFatalSignals[0]];
bool g_installed = false;

void write_stderr(const char* text) noexcept {
  const std::size_t n = strlen(text);
  const ssize_t written = write(STDERR_FILENO, text, n);
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

extern "C" void on_fatal_signal(int sig, siginfo_t* /*info*/, void* /*context*/) {
  // Only the first fatal signal drives the outputs: a second fault inside drive_safe() (or on
  // another thread meanwhile) must not loop. SA_RESETHAND has already restored the default
  // action, so returning (SIGSEGV re-faults) or the raise() below ends the process.
  if (g_handled.fetch_add(1) == 0) {
    if (Pipeline* p = g_pipeline.load()) {
      p->drive_safe();
      write_stderr("lode: ");
      write_stderr(signal_name(sig));
      write_stderr(": the process is dying of a bug; outputs driven to their safe values\n");
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
    for (std::size_t i = 0; i < sizeof kFatalSignals / sizeof kFatalSignals[0]; ++i) {
      struct sigaction sa{};
      sa.sa_sigaction = on_fatal_signal;
      sa.sa_flags = SA_SIGINFO | SA_RESETHAND | SA_ONSTACK;
      sigemptyset(&sa.sa_mask);
      (void)sigaction(kFatalSignals[i], &sa, &g_previous[i]);
    }
    g_installed = true;
  }
  g_pipeline.store(&pipeline);
}

CrashGuard::~CrashGuard() {
  g_pipeline.store(nullptr);
  if (g_installed) {
    for (std::size_t i = 0; i < sizeof kFatalSignals / sizeof kFatalSignals[0]; ++i)
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
