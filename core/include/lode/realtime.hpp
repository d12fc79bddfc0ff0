// Real-time settings of the host and of the RT thread, applied with graceful degradation.
//
// Each refusal (no privilege, no PREEMPT_RT, no such CPU) becomes a clear warning that the
// run reports, not a failure: a researcher's laptop still runs the pipeline, only with
// worse timing, and `lode rtcheck` explains how to fix the host.
#pragma once

#include <string>
#include <vector>

#include "lode/pipeline.hpp"

namespace lode {

/// One iteration of a polling loop: tells the core (and a hypervisor) that this is a spin, so a
/// sibling hyperthread keeps its share.
inline void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

/// Process-wide part: mlockall(MCL_CURRENT|MCL_FUTURE) and /dev/cpu_dma_latency = 0.
/// Returns warnings. Call before starting the RT thread.
std::vector<std::string> apply_process_realtime(const RealtimeSettings& settings);

/// The calling thread to SCHED_FIFO at `priority` (1..99): 0, or the error number why not
/// (EPERM without CAP_SYS_NICE or a high enough RLIMIT_RTPRIO).
int set_thread_fifo_priority(int priority) noexcept;

/// Thread part, called on the RT thread: SCHED_FIFO priority, CPU affinity, prefaulted stack.
std::vector<std::string> apply_thread_realtime(const RealtimeSettings& settings);

/// Undo the process-wide part (close the DMA latency request).
void release_process_realtime();

}  // namespace lode
