// The checks about the RT CPU: isolation, IRQs, frequency governor, SMT sibling, C-states.
// The RT CPU is the pipeline's realtime.cpu; unpinned, the isolated CPUs (where the loop
// belongs); with neither, the governor, SMT and C-state checks look at every online CPU.
#include <sstream>

#include "host_checks.hpp"

namespace lode::cli {

namespace {
constexpr const char* kCpuDir = "/sys/devices/system/cpu";
// An idle state whose exit takes longer than this delays the loop's wake-up noticeably.
constexpr long kDeepIdleLatencyUs = 10;

std::string cpu_path(int cpu, const std::string& rest) {
  return std::string(kCpuDir) + "/cpu" + std::to_string(cpu) + "/" + rest;
}

std::optional<std::set<int>> online_cpus(const HostFiles& files) {
  const auto text = files.read(std::string(kCpuDir) + "/online");
  return text ? parse_cpu_list(*text) : std::nullopt;
}

std::set<int> isolated_cpus(const HostFiles& files) {
  const auto text = files.read(std::string(kCpuDir) + "/isolated");
  return text ? parse_cpu_list(*text).value_or(std::set<int>{}) : std::set<int>{};
}

std::set<int> rt_cpus(const HostFiles& files, const HostTarget& t) {
  if (t.cpu >= 0) return {t.cpu};
  return isolated_cpus(files);
}

/// The CPUs whose governor, sibling and idle states matter: the RT CPU(s), else all.
std::set<int> inspected_cpus(const HostFiles& files, const HostTarget& t) {
  auto cpus = rt_cpus(files, t);
  if (cpus.empty()) cpus = online_cpus(files).value_or(std::set<int>{});
  return cpus;
}

/// The value of `name=` on the kernel command line ("" if absent).
std::string cmdline_value(const HostFiles& files, const std::string& name) {
  std::istringstream in(files.read("/proc/cmdline").value_or(""));
  for (std::string w; in >> w;)
    if (w.rfind(name + "=", 0) == 0) return w.substr(name.size() + 1);
  return "";
}

/// A CPU for the loop when none is chosen: the last one (CPU 0 carries most housekeeping).
int suggested_cpu(const HostFiles& files) {
  const auto online = online_cpus(files);
  return online && !online->empty() ? *online->rbegin() : 1;
}

std::string grub_fix(const std::string& params) {
  return "add " + params + " to GRUB_CMDLINE_LINUX in /etc/default/grub, then update-grub and reboot";
}

std::string cpu_word(const std::set<int>& cpus) {
  return (cpus.size() == 1 ? "CPU " : "CPUs ") + format_cpu_list(cpus);
}
}  // namespace

CheckResult check_isolation(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"isolated_cpus", CheckStatus::pass, "", ""};
  const auto online = online_cpus(files);
  const auto isolated_text = files.read(std::string(kCpuDir) + "/isolated");
  if (t.cpu >= 0 && online && !online->count(t.cpu)) {
    // lode run would run the loop unpinned: the pipeline was written for another host.
    r.status = CheckStatus::fail;
    r.found = "the pipeline's CPU " + std::to_string(t.cpu) + " does not exist (online: " + format_cpu_list(*online) + ")";
    r.fix = "set `realtime: { cpu: " + std::to_string(suggested_cpu(files)) + " }` in " +
            (t.config_path.empty() ? "the pipeline file" : t.config_path);
    return r;
  }
  if (!isolated_text) {
    r.status = CheckStatus::warn;
    r.found = "unknown: " + std::string(kCpuDir) + "/isolated missing";
    r.fix = "check /proc/cmdline for isolcpus=";
    return r;
  }
  const auto isolated = parse_cpu_list(*isolated_text).value_or(std::set<int>{});
  const int cpu = t.cpu >= 0 ? t.cpu : (isolated.empty() ? suggested_cpu(files) : *isolated.rbegin());
  const std::string n = std::to_string(cpu);
  if (online && online->size() < 2) {
    r.status = CheckStatus::warn;
    r.found = "one CPU only: nothing can be isolated for the loop";
    r.fix = "run the pipeline on a host with at least two cores";
    return r;
  }
  if (isolated.empty()) {
    // Without isolation the scheduler puts other tasks, kernel threads and timers on the
    // loop's CPU: SCHED_FIFO preempts them, but their cache and TLB footprint stays.
    r.status = CheckStatus::warn;
    r.found = "no isolated CPU";
    r.fix = grub_fix("isolcpus=" + n + " nohz_full=" + n + " rcu_nocbs=" + n) +
            (t.cpu >= 0 ? "" : "; then set `realtime: { cpu: " + n + " }` in the pipeline");
    return r;
  }
  if (t.cpu < 0) {
    if (t.from_pipeline()) {
      r.status = CheckStatus::warn;
      r.found = cpu_word(isolated) + " isolated, but the pipeline does not pin its loop to one";
      r.fix = "set `realtime: { cpu: " + n + " }` in " + t.config_path;
    } else {
      r.found = cpu_word(isolated) + " isolated";
    }
    return r;
  }
  if (!isolated.count(cpu)) {
    r.status = CheckStatus::warn;
    r.found = "the pipeline's CPU " + n + " is not isolated (isolated: " + format_cpu_list(isolated) + ")";
    r.fix = "set `realtime: { cpu: " + std::to_string(*isolated.rbegin()) + " }` in " + t.config_path + ", or " +
            grub_fix("isolcpus=" + n + " nohz_full=" + n + " rcu_nocbs=" + n);
    return r;
  }
  // Isolated: without nohz_full the tick still interrupts it, without rcu_nocbs RCU callbacks.
  const auto nohz = parse_cpu_list(files.read(std::string(kCpuDir) + "/nohz_full").value_or("")).value_or(std::set<int>{});
  const auto nocbs = parse_cpu_list(cmdline_value(files, "rcu_nocbs")).value_or(std::set<int>{});
  std::string missing;
  if (!nohz.count(cpu)) missing += " nohz_full=" + n;
  if (!nocbs.count(cpu)) missing += " rcu_nocbs=" + n;
  if (missing.empty()) {
    r.found = "CPU " + n + " isolated, nohz_full and rcu_nocbs";
    return r;
  }
  r.status = CheckStatus::warn;
  r.found = "CPU " + n + " isolated, but not" + missing + " (the tick or RCU callbacks still run there)";
  r.fix = grub_fix(missing.substr(1));
  return r;
}

CheckResult check_irq_affinity(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"irq_affinity", CheckStatus::pass, "", ""};
  const auto rt = rt_cpus(files, t);
  if (rt.empty()) {
    r.found = "not applicable: no RT CPU (the loop is not pinned and no CPU is isolated)";
    return r;
  }
  const auto irqs = files.list("/proc/irq");
  const auto online = online_cpus(files);
  if (irqs.empty() || !online) {
    r.status = CheckStatus::warn;
    r.found = "unknown: /proc/irq or " + std::string(kCpuDir) + "/online not readable";
    r.fix = "check `cat /proc/irq/*/smp_affinity_list` leaves out " + cpu_word(rt);
    return r;
  }
  std::set<int> housekeeping = *online;
  for (const int c : rt) housekeeping.erase(c);
  std::vector<std::string> on_rt;
  for (const auto& irq : irqs) {
    const auto list = files.read("/proc/irq/" + irq + "/smp_affinity_list");
    if (!list) continue;  // the directory's non-IRQ entries (default_smp_affinity)
    const auto cpus = parse_cpu_list(*list);
    if (!cpus) continue;
    for (const int c : rt)
      if (cpus->count(c)) {
        on_rt.push_back(irq);
        break;
      }
  }
  const auto default_mask = parse_cpu_mask(files.read("/proc/irq/default_smp_affinity").value_or(""));
  bool default_on_rt = false;
  for (const int c : rt) default_on_rt = default_on_rt || (default_mask && default_mask->count(c));
  if (on_rt.empty() && !default_on_rt) {
    r.found = "no IRQ may run on " + cpu_word(rt);
    return r;
  }
  // A device interrupt on the RT CPU delays the loop by its handler's run time (PREEMPT_RT
  // threads handlers, but the hard IRQ entry and the cache pollution remain).
  r.status = CheckStatus::warn;
  std::string list;
  for (std::size_t i = 0; i < on_rt.size() && i < 12; ++i) list += (i ? ", " : "") + on_rt[i];
  if (on_rt.size() > 12) list += " and " + std::to_string(on_rt.size() - 12) + " more";
  r.found = on_rt.empty() ? "" : "IRQs " + list + " may run on " + cpu_word(rt);
  if (default_on_rt)
    r.found += std::string(r.found.empty() ? "" : "; ") + "/proc/irq/default_smp_affinity includes " + cpu_word(rt);
  if (housekeeping.empty()) {
    r.fix = "no CPU is left for IRQs: use a host with more cores";
    return r;
  }
  const auto hk = format_cpu_list(housekeeping);
  r.fix = "for f in /proc/irq/*/smp_affinity_list; do echo " + hk + " > $f; done; echo " +
          format_cpu_mask(housekeeping) + " > /proc/irq/default_smp_affinity (for every boot: " +
          grub_fix("irqaffinity=" + hk) + "; with irqbalance, set IRQBALANCE_BANNED_CPULIST=" +
          format_cpu_list(rt) + " in /etc/default/irqbalance)";
  return r;
}

CheckResult check_governor(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"cpu_governor", CheckStatus::pass, "", ""};
  const auto cpus = inspected_cpus(files, t);
  std::set<int> unknown, slow;
  std::string seen;
  for (const int c : cpus) {
    const auto gov = files.read(cpu_path(c, "cpufreq/scaling_governor"));
    if (!gov) {
      unknown.insert(c);
    } else if (*gov != "performance") {
      slow.insert(c);
      seen += (seen.empty() ? "" : ", ") + ("cpu" + std::to_string(c) + ": " + *gov);
    }
  }
  if (cpus.empty() || unknown.size() == cpus.size()) {
    r.status = CheckStatus::warn;
    r.found = "unknown: no cpufreq/scaling_governor (a VM, or frequency set by the firmware)";
    r.fix = "in the BIOS/UEFI setup, disable SpeedStep/Cool'n'Quiet and turbo for a fixed clock";
    return r;
  }
  if (slow.empty()) {
    r.found = "performance governor on " + cpu_word(cpus);
    return r;
  }
  // A ramping governor runs the loop slower after idle periods and changes its cost.
  r.status = CheckStatus::warn;
  r.found = "not 'performance' (" + seen + "): the clock ramps, the cycle cost varies";
  for (const int c : slow)
    r.fix += (r.fix.empty() ? "" : "; ") + ("echo performance > " + cpu_path(c, "cpufreq/scaling_governor"));
  r.fix += " (for every boot: cpufrequtils' GOVERNOR=performance in /etc/default/cpufrequtils)";
  return r;
}

CheckResult check_smt(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"smt", CheckStatus::pass, "", ""};
  const auto active = files.read(std::string(kCpuDir) + "/smt/active");
  if (active && *active == "0") {
    r.found = "SMT off";
    return r;
  }
  const auto rt = rt_cpus(files, t);
  const std::string smt_fix = "echo off > /sys/devices/system/cpu/smt/control (for every boot: " + grub_fix("nosmt") + ")";
  std::set<int> siblings;
  bool any_read = false;
  for (const int c : rt) {
    const auto list = files.read(cpu_path(c, "topology/thread_siblings_list"));
    if (!list) continue;
    any_read = true;
    for (const int s : parse_cpu_list(*list).value_or(std::set<int>{}))
      if (!rt.count(s)) siblings.insert(s);
  }
  if (!rt.empty() && any_read) {
    if (siblings.empty()) {
      r.found = cpu_word(rt) + " shares its core with no other CPU";
      return r;
    }
    // The sibling hyperthread shares the core's execution units and caches: whatever runs
    // there slows the loop's cycle unpredictably.
    r.status = CheckStatus::warn;
    r.found = cpu_word(rt) + " shares its core with " + cpu_word(siblings);
    r.fix = smt_fix + ", or keep the sibling idle too: isolcpus=" + format_cpu_list(rt) + "," + format_cpu_list(siblings);
    return r;
  }
  if (!active) {
    r.status = CheckStatus::warn;
    r.found = "unknown: " + std::string(kCpuDir) + "/smt/active and thread_siblings_list missing";
    r.fix = "check `lscpu` says 'Thread(s) per core: 1'; if not, " + smt_fix;
    return r;
  }
  r.status = CheckStatus::warn;
  r.found = "SMT on (no RT CPU chosen to check its sibling)";
  r.fix = smt_fix + ", or isolate both threads of the loop's core";
  return r;
}

CheckResult check_cstates(const HostFiles& files, const HostTarget& t) {
  CheckResult r{"cstates", CheckStatus::pass, "", ""};
  const auto cpus = inspected_cpus(files, t);
  std::string deep;
  bool any_dir = false;
  for (const int c : cpus) {
    for (const auto& state : files.list(cpu_path(c, "cpuidle"))) {
      if (state.rfind("state", 0) != 0) continue;
      any_dir = true;
      const auto dir = cpu_path(c, "cpuidle/" + state + "/");
      if (files.read(dir + "disable").value_or("0") != "0") continue;
      const long latency = std::strtol(files.read(dir + "latency").value_or("0").c_str(), nullptr, 10);
      if (latency > kDeepIdleLatencyUs)
        deep += (deep.empty() ? "" : ", ") + ("cpu" + std::to_string(c) + " " +
                 files.read(dir + "name").value_or(state) + " " + std::to_string(latency) + " us");
    }
  }
  const bool dma_writable = files.writable("/dev/cpu_dma_latency");
  if (!any_dir) {
    const auto driver = files.read(std::string(kCpuDir) + "/cpuidle/current_driver");
    if (driver && *driver == "none") {
      r.found = "no cpuidle driver: idle CPUs halt (HLT), no deep C-state";
    } else {
      r.status = CheckStatus::warn;
      r.found = "unknown: no cpuidle states under " + std::string(kCpuDir) + "/cpuN/cpuidle";
      r.fix = "check `cpupower idle-info`; keep deep states off with " +
              grub_fix("processor.max_cstate=1 intel_idle.max_cstate=0");
    }
    return r;
  }
  if (deep.empty()) {
    r.found = "no enabled idle state exits slower than " + std::to_string(kDeepIdleLatencyUs) + " us";
    return r;
  }
  if (dma_writable && t.priority > 0) {
    // lode run writes 0 to /dev/cpu_dma_latency (when it runs SCHED_FIFO): the PM QoS
    // request keeps every CPU out of these states while it runs.
    r.found = "deep idle states enabled (" + deep + "), kept off while lode runs (/dev/cpu_dma_latency is writable)";
    return r;
  }
  // Waking from a deep C-state takes the listed exit latency on top of the timer's.
  r.status = CheckStatus::warn;
  r.found = "deep idle states enabled (" + deep + ") and " +
            (dma_writable ? std::string("the pipeline asks no SCHED_FIFO priority, so lode run does not hold /dev/cpu_dma_latency")
                          : std::string("/dev/cpu_dma_latency is not writable for this user"));
  r.fix = grub_fix("processor.max_cstate=1 intel_idle.max_cstate=0") +
          ", or let the lode user write /dev/cpu_dma_latency (a udev rule: KERNEL==\"cpu_dma_latency\", GROUP=\"realtime\", MODE=\"0660\")";
  return r;
}

}  // namespace lode::cli
