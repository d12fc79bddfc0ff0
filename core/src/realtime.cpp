#include "lode/realtime.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <thread>

namespace lode {

namespace {
int g_dma_latency_fd = -1;

/// Touch a block of stack so its pages are mapped (and locked) before the loop starts.
void prefault_stack() {
  constexpr std::size_t kBytes = 256 * 1024;
  unsigned char buffer[kBytes];
  std::memset(buffer, 0, kBytes);
  asm volatile("" : : "r"(buffer) : "memory");  // keep the stores: the point is the page faults
}
}  // namespace

std::vector<std::string> apply_process_realtime(const RealtimeSettings& s) {
  std::vector<std::string> warnings;
  if (s.lock_memory) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
      warnings.push_back(std::string("mlockall refused (") + std::strerror(errno) +
                         "): memory may page out; run as root or raise RLIMIT_MEMLOCK "
                         "(`ulimit -l unlimited`)");
  }
  if (s.priority > 0 && g_dma_latency_fd < 0) {
    // Keep the CPUs out of deep C-states while the loop runs (the PM QoS interface).
    g_dma_latency_fd = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
    if (g_dma_latency_fd >= 0) {
      const std::int32_t zero = 0;
      if (write(g_dma_latency_fd, &zero, sizeof zero) != static_cast<ssize_t>(sizeof zero)) {
        close(g_dma_latency_fd);
        g_dma_latency_fd = -1;
      }
    }
  }
  return warnings;
}

void release_process_realtime() {
  if (g_dma_latency_fd >= 0) {
    close(g_dma_latency_fd);
    g_dma_latency_fd = -1;
  }
}

int set_thread_fifo_priority(int priority) noexcept {
  sched_param sp{};
  sp.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
}

std::vector<std::string> apply_thread_realtime(const RealtimeSettings& s) {
  std::vector<std::string> warnings;
  if (s.cpu >= 0) {
    const auto ncpu = static_cast<int>(std::thread::hardware_concurrency());
    if (s.cpu >= ncpu) {
      warnings.push_back("cpu " + std::to_string(s.cpu) + " does not exist (this host has " +
                         std::to_string(ncpu) + "): the RT thread is not pinned");
    } else {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(s.cpu, &set);
      if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set); rc != 0)
        warnings.push_back(std::string("CPU affinity refused (") + std::strerror(rc) +
                           "): the RT thread may migrate between CPUs");
    }
  }
  if (s.priority > 0) {
    if (const int rc = set_thread_fifo_priority(s.priority); rc != 0)
      warnings.push_back(std::string("SCHED_FIFO priority ") + std::to_string(s.priority) +
                         " refused (" + std::strerror(rc) +
                         "): the loop runs with normal scheduling; run as root or grant "
                         "CAP_SYS_NICE / RLIMIT_RTPRIO (see `lode rtcheck`)");
  }
  if (s.lock_memory) prefault_stack();
  return warnings;
}

}  // namespace lode
