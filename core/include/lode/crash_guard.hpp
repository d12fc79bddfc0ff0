// Safe outputs when the process dies of a bug: a plugin that dereferences a bad
// pointer, divides by zero, or lets an exception escape a noexcept step() (std::terminate ->
// abort). On SIGSEGV, SIGBUS, SIGFPE, SIGILL or SIGABRT the armed pipeline's io blocks drive
// their outputs to the safe values, one line on stderr says so, and the process dies of the
// same signal as it would have (exit status, core dump). SIGKILL and power loss cannot be
// caught in the process: the board's or module's own watchdog must cover those.
//
//   CrashGuard guard(pipeline);   // while the pipeline is active; disarmed by the destructor
//
// drive_safe() is called from a signal handler here, so io blocks keep it async-signal-safe
// (register writes, send(2); no allocation, no lock), as the RT rules already require. The
// handlers run on an alternate stack, so a stack overflow is caught too: the constructing
// thread's, and each thread holding an AlternateSignalStack (the scheduler's RT thread does).
#pragma once

#include <memory>

namespace lode {

class Pipeline;

class CrashGuard {
 public:
  explicit CrashGuard(Pipeline& pipeline);
  ~CrashGuard();
  CrashGuard(const CrashGuard&) = delete;
  CrashGuard& operator=(const CrashGuard&) = delete;
};

/// An alternate signal stack for the calling thread while this object lives (sigaltstack is per
/// thread). Made at a thread's start, off the RT path: it allocates.
class AlternateSignalStack {
 public:
  AlternateSignalStack();
  ~AlternateSignalStack();
  AlternateSignalStack(const AlternateSignalStack&) = delete;
  AlternateSignalStack& operator=(const AlternateSignalStack&) = delete;

 private:
  std::unique_ptr<char[]> stack_;
  bool installed_ = false;
};

}  // namespace lode
