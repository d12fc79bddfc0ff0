#include "lode/realtime.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

namespace lode {

namespace {
int g_dma_latency_fd = -1;

std::string read_file(const char* path) {
  std::ifstream in(path);
  if (!in) return {};
  std::stringstream ss;
  ss << in.rdbuf();
  auto s = ss.str();
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

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
    sched_param sp{};
    sp.sched_priority = s.priority;
    if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); rc != 0)
      warnings.push_back(std::string("SCHED_FIFO priority ") + std::to_string(s.priority) +
                         " refused (" + std::strerror(rc) +
                         "): the loop runs with normal scheduling; run as root or grant "
                         "CAP_SYS_NICE / RLIMIT_RTPRIO (see `lode rtcheck`)");
  }
  if (s.lock_memory) prefault_stack();
  return warnings;
}

Json realtime_host_report() {
  Json r = Json::object();
  utsname u{};
  uname(&u);
  const std::string version = u.version;
  const std::string rt_flag = read_file("/sys/kernel/realtime");
  const bool preempt_rt = rt_flag == "1" || version.find("PREEMPT_RT") != std::string::npos;
  Json k = Json::object();
  k["release"] = u.release;
  k["version"] = version;
  k["preempt_rt"] = preempt_rt;
  k["advice"] = preempt_rt ? "ok"
                           : "not a PREEMPT_RT kernel: expect millisecond latency spikes; install "
                             "linux-image-rt-amd64 (Debian) and boot it for production stages";
  r["kernel"] = std::move(k);

  rlimit rl{};
  getrlimit(RLIMIT_RTPRIO, &rl);
  const bool root = geteuid() == 0;
  Json p = Json::object();
  p["root"] = root;
  p["rlimit_rtprio"] = static_cast<std::int64_t>(rl.rlim_cur);
  getrlimit(RLIMIT_MEMLOCK, &rl);
  p["rlimit_memlock_bytes"] = rl.rlim_cur == RLIM_INFINITY ? Json("unlimited")
                                                           : Json(static_cast<std::int64_t>(rl.rlim_cur));
  // Try SCHED_FIFO on a short-lived thread: the honest answer to "will it work?".
  bool fifo_ok = false;
  std::thread probe([&] {
    sched_param sp{};
    sp.sched_priority = 1;
    fifo_ok = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  });
  probe.join();
  p["sched_fifo_allowed"] = fifo_ok;
  p["advice"] = fifo_ok ? "ok"
                        : "SCHED_FIFO refused: run as root, or add `@realtime - rtprio 99` and "
                          "`@realtime - memlock unlimited` to /etc/security/limits.conf";
  r["privileges"] = std::move(p);

  Json c = Json::object();
  c["online"] = static_cast<int>(std::thread::hardware_concurrency());
  c["isolated"] = read_file("/sys/devices/system/cpu/isolated");
  c["rt_runtime_us"] = read_file("/proc/sys/kernel/sched_rt_runtime_us");
  c["clocksource"] = read_file("/sys/devices/system/clocksource/clocksource0/current_clocksource");
  c["advice"] = c.find("isolated")->as_string().empty()
                    ? "no isolated CPU: consider isolcpus=/nohz_full= on the kernel command line "
                      "and `realtime: {cpu: N}` in the pipeline"
                    : "ok";
  r["cpus"] = std::move(c);
  return r;
}

}  // namespace lode
