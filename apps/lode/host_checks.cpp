// The checks of the process's rights and of the kernel as a whole; host_cpu_checks.cpp has
// those about the RT CPU.
#include "host_checks.hpp"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <sstream>

namespace lode::cli {

namespace {
constexpr int kCapIpcLock = 14;  // linux/capability.h
constexpr int kCapSysNice = 23;
// A finite memlock limit this large holds a lode process (tens of MB with Fast DDS) with
// margin, so it only warns; below it mlockall(MCL_FUTURE) soon refuses allocations.
constexpr std::uint64_t kEnoughMemlockBytes = 1ULL << 30;
constexpr const char* kLimitsFix =
    "add '@realtime - rtprio 99' and '@realtime - memlock unlimited' to a file in "
    "/etc/security/limits.d/, add the user to the realtime group (adduser USER realtime) and log "
    "in again; the lode@ service needs neither: its unit sets LimitRTPRIO=99 and LimitMEMLOCK=infinity";

std::string in_config(const HostTarget& t) { return t.config_path.empty() ? "the pipeline file" : t.config_path; }

std::string bytes_text(std::uint64_t b) {
  if (b >= (1ULL << 20)) return std::to_string(b >> 20) + " MiB";
  if (b >= (1ULL << 10)) return std::to_string(b >> 10) + " KiB";
  return std::to_string(b) + " B";
}

std::optional<long long> parse_integer(const std::string& text) {
  long long v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return v;
}

/// Whether lode run will hold its memory locked: the pipeline asks and the process may.
bool memory_lockable(const ProcessFacts& p) {
  return p.has_cap(kCapIpcLock) || (p.limits_known && !p.memlock_limit);
}
}  // namespace

const char* status_name(CheckStatus s) {
  switch (s) {
    case CheckStatus::pass: return "PASS";
    case CheckStatus::warn: return "WARN";
    case CheckStatus::fail: return "FAIL";
  }
  return "?";
}

CheckResult check_kernel(const HostFiles& files) {
  CheckResult r{"kernel", CheckStatus::pass, "", ""};
  const auto flag = files.read("/sys/kernel/realtime");
  const auto version = files.read("/proc/sys/kernel/version");  // what `uname -v` prints
  const auto release = files.read("/proc/sys/kernel/osrelease").value_or("?");
  if (!flag && !version) {
    r.status = CheckStatus::warn;
    r.found = "unknown: neither /sys/kernel/realtime nor /proc/sys/kernel/version is readable";
    r.fix = "run `uname -v` and check that it says PREEMPT_RT; if not, apt-get install linux-image-rt-amd64 and boot it";
    return r;
  }
  const bool rt = (flag && *flag == "1") || (version && version->find("PREEMPT_RT") != std::string::npos);
  if (rt) {
    r.found = "PREEMPT_RT kernel " + release;
    return r;
  }
  // A kernel without PREEMPT_RT cannot preempt long kernel sections: wake-ups of the loop are
  // late by up to milliseconds under disk or network load, whatever the priority.
  r.status = CheckStatus::fail;
  r.found = "kernel " + release + " is not PREEMPT_RT (" + version.value_or("no /proc/sys/kernel/version") + ")";
  r.fix = "apt-get install linux-image-rt-amd64, then reboot into it (make it GRUB's default: "
          "GRUB_DEFAULT in /etc/default/grub, then update-grub)";
  return r;
}

CheckResult check_rtprio(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"rtprio", CheckStatus::pass, "", ""};
  if (t.priority <= 0) {
    // Not a host problem, but the loop then competes with every other task on its CPU.
    r.status = CheckStatus::warn;
    r.found = "the pipeline asks for no SCHED_FIFO priority (realtime.priority 0): normal scheduling";
    r.fix = "set `realtime: { priority: 80 }` in " + in_config(t);
    return r;
  }
  const auto p = read_process_facts(files);
  const std::string want = "SCHED_FIFO priority " + std::to_string(t.priority);
  if (p.known && p.has_cap(kCapSysNice)) {
    r.found = want + ": allowed (CAP_SYS_NICE" + std::string(p.uid == 0 ? ", root" : "") + ")";
    return r;
  }
  if (!p.known || !p.limits_known) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /proc/self/status or /proc/self/limits is not readable";
    r.fix = std::string("check `ulimit -r` (must be at least ") + std::to_string(t.priority) + "); " + kLimitsFix;
    return r;
  }
  if (*p.rtprio_limit >= static_cast<std::uint64_t>(t.priority)) {
    r.found = want + ": allowed (RLIMIT_RTPRIO " + std::to_string(*p.rtprio_limit) + ")";
    return r;
  }
  // lode run would fall back to normal scheduling: the loop is as late as any desktop task.
  r.status = CheckStatus::fail;
  r.found = want + " refused: RLIMIT_RTPRIO is " + std::to_string(*p.rtprio_limit) + " and no CAP_SYS_NICE";
  r.fix = kLimitsFix;
  return r;
}

CheckResult check_memlock(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"memlock", CheckStatus::pass, "", ""};
  if (!t.lock_memory) {
    r.status = CheckStatus::warn;
    r.found = "the pipeline does not lock its memory (realtime.lock_memory false): a page fault in the loop costs milliseconds";
    r.fix = "set `realtime: { lock_memory: true }` in " + in_config(t);
    return r;
  }
  const auto p = read_process_facts(files);
  if (p.known && p.has_cap(kCapIpcLock)) {
    r.found = "mlockall allowed (CAP_IPC_LOCK" + std::string(p.uid == 0 ? ", root" : "") + ")";
    return r;
  }
  if (!p.limits_known) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /proc/self/limits is not readable";
    r.fix = std::string("check `ulimit -l` (should say unlimited); ") + kLimitsFix;
    return r;
  }
  if (!p.memlock_limit) {
    r.found = "mlockall allowed (RLIMIT_MEMLOCK unlimited)";
    return r;
  }
  r.found = "RLIMIT_MEMLOCK is " + bytes_text(*p.memlock_limit) + " and no CAP_IPC_LOCK";
  r.fix = kLimitsFix;
  // Below the threshold lode run's mlockall fails outright or later allocations do.
  r.status = *p.memlock_limit >= kEnoughMemlockBytes ? CheckStatus::warn : CheckStatus::fail;
  r.found += r.status == CheckStatus::warn ? ": enough unless the process grows beyond it"
                                           : ": too little to lock a lode process";
  return r;
}

CheckResult check_realtime_group(const HostFiles& files) {
  // Only a WARN: the rtprio and memlock checks fail when the limits the group carries are
  // missing; this one says how a user gets them.
  CheckResult r{"realtime_group", CheckStatus::pass, "", ""};
  const auto p = read_process_facts(files);
  const auto group_file = files.read("/etc/group");
  if (!group_file || !p.known) {
    r.status = CheckStatus::warn;
    r.found = std::string("unknown: ") + (group_file ? "/proc/self/status" : "/etc/group") + " is not readable";
    r.fix = "check `id` lists the realtime group; if not: adduser USER realtime";
    return r;
  }
  std::optional<std::uint32_t> gid;
  std::istringstream in(*group_file);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("realtime:", 0) != 0) continue;
    const auto a = line.find(':', 9), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    if (const auto v = parse_integer(line.substr(a + 1, b - a - 1)); v && *v >= 0 && *v <= UINT32_MAX)
      gid = static_cast<std::uint32_t>(*v);
  }
  std::string user = p.uid == 0 ? "root" : "uid " + std::to_string(p.uid);
  if (const auto passwd = files.read("/etc/passwd")) {
    std::istringstream pw(*passwd);
    for (std::string line; std::getline(pw, line);) {
      const auto a = line.find(':'), b = line.find(':', a + 1), c = line.find(':', b + 1);
      if (c != std::string::npos && line.substr(b + 1, c - b - 1) == std::to_string(p.uid)) user = line.substr(0, a);
    }
  }
  if (!gid) {
    r.status = CheckStatus::warn;
    r.found = "no 'realtime' group on this host";
    r.fix = "addgroup --system realtime, give it limits ('@realtime - rtprio 99', '@realtime - memlock "
            "unlimited' in a file in /etc/security/limits.d/), then adduser " + (p.uid == 0 ? std::string("USER") : user) +
            " realtime for each user who runs lode by hand";
    return r;
  }
  const bool member = std::find(p.groups.begin(), p.groups.end(), *gid) != p.groups.end();
  if (member) {
    r.found = user + " is in the realtime group";
  } else if (p.uid == 0) {
    r.found = "root: needs no group (the lode@ service runs with Group=realtime)";
  } else {
    r.status = CheckStatus::warn;
    r.found = user + " is not in the realtime group";
    r.fix = "adduser " + user + " realtime, then log in again";
  }
  return r;
}

CheckResult check_rt_throttling(const HostFiles& files) {
  CheckResult r{"rt_throttling", CheckStatus::pass, "", ""};
  const auto runtime_text = files.read("/proc/sys/kernel/sched_rt_runtime_us");
  const auto period_text = files.read("/proc/sys/kernel/sched_rt_period_us");
  const auto runtime_value = runtime_text ? parse_integer(*runtime_text) : std::nullopt;
  const auto period_value = period_text ? parse_integer(*period_text) : std::nullopt;
  const long long runtime = runtime_value.value_or(0), period = period_value.value_or(0);
  if (!runtime_value || (runtime >= 0 && period <= 0)) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /proc/sys/kernel/sched_rt_runtime_us or sched_rt_period_us missing or unreadable";
    r.fix = "check `sysctl kernel.sched_rt_runtime_us` (950000 or -1 are fine)";
    return r;
  }
  const std::string fix = "sysctl -w kernel.sched_rt_runtime_us=950000 (and put "
                          "kernel.sched_rt_runtime_us = 950000 in a file in /etc/sysctl.d/)";
  if (runtime < 0) {
    r.found = "RT throttling off (sched_rt_runtime_us -1)";
  } else if (runtime == 0) {
    // No runtime for RT tasks at all: a SCHED_FIFO loop never runs.
    r.status = CheckStatus::fail;
    r.found = "sched_rt_runtime_us is 0: SCHED_FIFO tasks get no CPU time";
    r.fix = fix;
  } else if (runtime * 100 >= period * 95) {
    // The default safety net: only a loop that hogs more than 95 % of its CPU is throttled.
    r.found = "RT tasks may use " + std::to_string(runtime) + " of every " + std::to_string(period) +
              " us (only a runaway loop is throttled)";
  } else {
    r.status = CheckStatus::warn;
    r.found = "RT tasks may use only " + std::to_string(runtime) + " of every " + std::to_string(period) +
              " us: a busy loop is stopped for the rest of each period";
    r.fix = fix;
  }
  return r;
}

CheckResult check_transparent_hugepages(const HostFiles& files) {
  CheckResult r{"transparent_hugepages", CheckStatus::pass, "", ""};
  const auto thp = files.read("/sys/kernel/mm/transparent_hugepage/enabled");
  const std::string fix = "echo madvise > /sys/kernel/mm/transparent_hugepage/enabled (for every boot: "
                          "transparent_hugepage=madvise on the kernel command line)";
  if (!thp) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /sys/kernel/mm/transparent_hugepage/enabled missing";
    r.fix = "if the kernel has THP, keep it off 'always': " + fix;
    return r;
  }
  if (thp->find("[always]") != std::string::npos) {
    // khugepaged compacts and collapses pages behind the loop's back: sporadic stalls.
    r.status = CheckStatus::warn;
    r.found = "transparent huge pages 'always' (" + *thp + "): page compaction may stall the loop";
    r.fix = fix;
  } else {
    r.found = "transparent huge pages: " + *thp;
  }
  return r;
}

CheckResult check_swap(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"swap", CheckStatus::pass, "", ""};
  const auto swaps = files.read("/proc/swaps");
  if (!swaps) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /proc/swaps missing";
    r.fix = "check `swapon --show`; with swap, keep realtime.lock_memory true";
    return r;
  }
  std::istringstream in(*swaps);
  std::vector<std::string> devices;
  std::string line;
  std::getline(in, line);  // the header
  while (std::getline(in, line)) {
    std::istringstream w(line);
    std::string dev;
    if (w >> dev) devices.push_back(dev);
  }
  if (devices.empty()) {
    r.found = "no swap";
    return r;
  }
  std::string list;
  for (const auto& d : devices) list += (list.empty() ? "" : ", ") + d;
  if (t.lock_memory && memory_lockable(read_process_facts(files))) {
    r.found = "swap on (" + list + "), but the loop's memory is locked";
    return r;
  }
  r.status = CheckStatus::warn;
  r.found = "swap on (" + list + ") and the loop's memory is not locked: a page swapped out stalls the loop";
  r.fix = "set `realtime: { lock_memory: true }` in " + in_config(t) +
          " and allow locking (see memlock), or swapoff -a and remove the swap lines from /etc/fstab";
  return r;
}

std::vector<CheckResult> run_host_checks(const HostFiles& files, const HostTarget& target) {
  return {check_kernel(files),
          check_rtprio(files, target),
          check_memlock(files, target),
          check_realtime_group(files),
          check_rt_throttling(files),
          check_isolation(files, target),
          check_irq_affinity(files, target),
          check_governor(files, target),
          check_smt(files, target),
          check_cstates(files, target),
          check_transparent_hugepages(files),
          check_swap(files, target)};
}

bool host_fit(const std::vector<CheckResult>& checks) {
  for (const auto& c : checks)
    if (c.status == CheckStatus::fail) return false;
  return true;
}

std::string checks_text(const std::vector<CheckResult>& checks) {
  std::string out;
  for (const auto& c : checks) {
    char head[64];
    std::snprintf(head, sizeof head, "%s  %-22s ", status_name(c.status), c.name.c_str());
    out += head + c.found + "\n";
    if (!c.fix.empty()) out += std::string(30, ' ') + "fix: " + c.fix + "\n";
  }
  return out;
}

Json checks_json(const std::vector<CheckResult>& checks) {
  Json a = Json::array();
  for (const auto& c : checks) {
    Json j = Json::object();
    j["name"] = c.name;
    j["status"] = status_name(c.status);
    j["found"] = c.found;
    j["fix"] = c.fix;
    a.push(std::move(j));
  }
  return a;
}

}  // namespace lode::cli
