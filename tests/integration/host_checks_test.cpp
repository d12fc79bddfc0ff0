// `lode rtcheck`'s checks on fake hosts: a /sys + /proc + /etc + /dev tree in a temporary
// folder, first a host fit in every way (every check PASS), then each check's finding broken
// one at a time (its WARN or FAIL, and the fix text that names the exact change), and every
// file missing ("unknown", never a crash). Also the exit rule (fit = no FAIL), the report's
// text and JSON, and the latency findings on synthetic measurements.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "host_checks.hpp"
#include "rtcheck_latency.hpp"

namespace {

using namespace lode::cli;
namespace fs = std::filesystem;

/// A fake root, filled with a host fit for a pipeline pinned to CPU 3 of 4.
class FakeHost {
 public:
  FakeHost() {
    std::string pattern = (fs::temp_directory_path() / "lode_host_checks_XXXXXX").string();
    if (::mkdtemp(pattern.data()) != nullptr) root_ = pattern;
    write("/sys/kernel/realtime", "1\n");
    write("/proc/sys/kernel/version", "#1 SMP PREEMPT_RT Debian 6.1.99-1 (2024-07-15)\n");
    write("/proc/sys/kernel/osrelease", "6.1.0-23-rt-amd64\n");
    write("/proc/self/status", "Name:\tlode\nUid:\t1000\t1000\t1000\t1000\nGroups:\t27 998 \nCapEff:\t0000000000000000\n");
    limits("99", "unlimited");
    write("/etc/group", "sudo:x:27:lab\nrealtime:x:998:lab\n");
    write("/etc/passwd", "root:x:0:0:root:/root:/bin/bash\nlab:x:1000:1000::/home/lab:/bin/bash\n");
    write("/proc/sys/kernel/sched_rt_runtime_us", "950000\n");
    write("/proc/sys/kernel/sched_rt_period_us", "1000000\n");
    write("/sys/devices/system/cpu/online", "0-3\n");
    write("/sys/devices/system/cpu/isolated", "3\n");
    write("/sys/devices/system/cpu/nohz_full", "3\n");
    write("/proc/cmdline", "BOOT_IMAGE=/vmlinuz-6.1.0-23-rt-amd64 ro quiet isolcpus=3 nohz_full=3 rcu_nocbs=3\n");
    write("/proc/irq/24/smp_affinity_list", "0-2\n");
    write("/proc/irq/25/smp_affinity_list", "1\n");
    write("/proc/irq/default_smp_affinity", "7\n");
    write("/sys/devices/system/cpu/cpu3/cpufreq/scaling_governor", "performance\n");
    write("/sys/devices/system/cpu/smt/active", "0\n");
    write("/sys/devices/system/cpu/cpu3/topology/thread_siblings_list", "3\n");
    idle_state(0, "POLL", 0, false);
    idle_state(1, "C1", 2, false);
    idle_state(2, "C6", 133, false);
    write("/dev/cpu_dma_latency", "");
    write("/sys/kernel/mm/transparent_hugepage/enabled", "always [madvise] never\n");
    write("/proc/swaps", "Filename\t\t\t\tType\t\tSize\t\tUsed\t\tPriority\n/dev/sda3 partition\t8388604\t0\t-2\n");
  }
  ~FakeHost() {
    std::error_code ec;
    if (!root_.empty()) fs::remove_all(root_, ec);
  }
  FakeHost(const FakeHost&) = delete;
  FakeHost& operator=(const FakeHost&) = delete;

  void write(const std::string& path, const std::string& text) const {
    fs::create_directories(fs::path(root_ + path).parent_path());
    std::ofstream(root_ + path) << text;
  }
  void remove(const std::string& path) const { fs::remove_all(root_ + path); }
  void limits(const std::string& rtprio, const std::string& memlock) const {
    write("/proc/self/limits",
          "Limit                     Soft Limit           Hard Limit           Units     \n"
          "Max cpu time              unlimited            unlimited            seconds   \n"
          "Max locked memory         " + memlock + "             " + memlock + "             bytes     \n"
          "Max realtime priority     " + rtprio + "                    " + rtprio + "                    \n");
  }
  void idle_state(int n, const std::string& name, int latency_us, bool disabled) const {
    const auto dir = "/sys/devices/system/cpu/cpu3/cpuidle/state" + std::to_string(n) + "/";
    write(dir + "name", name + "\n");
    write(dir + "latency", std::to_string(latency_us) + "\n");
    write(dir + "disable", disabled ? "1\n" : "0\n");
  }
  [[nodiscard]] HostFiles files() const { return HostFiles(root_); }
  [[nodiscard]] const std::string& root() const { return root_; }

 private:
  std::string root_;
};

HostTarget pipeline_on_cpu3() {
  HostTarget t;
  t.pipeline = "stage";
  t.config_path = "stage.yaml";
  t.priority = 80;
  t.cpu = 3;
  t.lock_memory = true;
  t.period_ns = 1'250'000;
  return t;
}

::testing::AssertionResult is(const CheckResult& r, CheckStatus want, const std::string& fix_has = "") {
  if (r.status != want)
    return ::testing::AssertionFailure() << r.name << " is " << status_name(r.status) << ", expected "
                                         << status_name(want) << " (found: " << r.found << ")";
  if (want == CheckStatus::pass && !r.fix.empty())
    return ::testing::AssertionFailure() << r.name << " passes but gives a fix: " << r.fix;
  if (want != CheckStatus::pass && r.fix.empty())
    return ::testing::AssertionFailure() << r.name << " is " << status_name(want) << " without a fix";
  if (r.fix.find(fix_has) == std::string::npos)
    return ::testing::AssertionFailure() << r.name << "'s fix does not say '" << fix_has << "': " << r.fix;
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult unknown(const CheckResult& r) {
  if (r.status != CheckStatus::warn || r.found.rfind("unknown", 0) != 0)
    return ::testing::AssertionFailure() << r.name << " with its file missing is " << status_name(r.status) << ": "
                                         << r.found;
  return ::testing::AssertionSuccess();
}

TEST(HostChecks, AFitHostPassesEveryCheck) {
  FakeHost host;
  const auto checks = run_host_checks(host.files(), pipeline_on_cpu3());
  ASSERT_EQ(checks.size(), 12U);
  for (const auto& c : checks) EXPECT_TRUE(is(c, CheckStatus::pass));
  EXPECT_TRUE(host_fit(checks));
}

TEST(HostChecks, Kernel) {
  FakeHost host;
  EXPECT_TRUE(is(check_kernel(host.files()), CheckStatus::pass));
  host.remove("/sys/kernel/realtime");  // older RT kernels: only `uname -v` says it
  EXPECT_TRUE(is(check_kernel(host.files()), CheckStatus::pass));
  host.write("/proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.99-1\n");
  EXPECT_TRUE(is(check_kernel(host.files()), CheckStatus::fail, "apt-get install linux-image-rt-amd64"));
  host.write("/sys/kernel/realtime", "0\n");
  EXPECT_TRUE(is(check_kernel(host.files()), CheckStatus::fail, "linux-image-rt-amd64"));
  host.remove("/sys/kernel/realtime");
  host.remove("/proc/sys/kernel/version");
  EXPECT_TRUE(unknown(check_kernel(host.files())));
}

TEST(HostChecks, RtprioLimit) {
  FakeHost host;
  auto t = pipeline_on_cpu3();
  host.limits("50", "unlimited");  // below the pipeline's 80
  const auto r = check_rtprio(host.files(), t);
  EXPECT_TRUE(is(r, CheckStatus::fail, "@realtime - rtprio 99"));
  EXPECT_NE(r.found.find("RLIMIT_RTPRIO is 50"), std::string::npos) << r.found;
  t.priority = 40;  // within the limit
  EXPECT_TRUE(is(check_rtprio(host.files(), t), CheckStatus::pass));
  t.priority = 80;
  host.write("/proc/self/status", "Uid:\t0\t0\t0\t0\nGroups:\t0\nCapEff:\t000001ffffffffff\n");  // root
  EXPECT_TRUE(is(check_rtprio(host.files(), t), CheckStatus::pass));
  t.priority = 0;
  EXPECT_TRUE(is(check_rtprio(host.files(), t), CheckStatus::warn, "priority: 80 }` in stage.yaml"));
  t.priority = 80;
  host.remove("/proc/self/status");
  EXPECT_TRUE(unknown(check_rtprio(host.files(), t)));
}

TEST(HostChecks, MemlockLimit) {
  FakeHost host;
  auto t = pipeline_on_cpu3();
  host.limits("99", "8388608");  // Debian's default 8 MiB
  auto r = check_memlock(host.files(), t);
  EXPECT_TRUE(is(r, CheckStatus::fail, "@realtime - memlock unlimited"));
  EXPECT_NE(r.found.find("8 MiB"), std::string::npos) << r.found;
  host.limits("99", "4294967296");
  EXPECT_TRUE(is(check_memlock(host.files(), t), CheckStatus::warn, "memlock unlimited"));
  host.write("/proc/self/status", "Uid:\t1000\t1000\t1000\t1000\nGroups:\t998\nCapEff:\t0000000000004000\n");
  EXPECT_TRUE(is(check_memlock(host.files(), t), CheckStatus::pass));  // CAP_IPC_LOCK
  t.lock_memory = false;
  EXPECT_TRUE(is(check_memlock(host.files(), t), CheckStatus::warn, "lock_memory: true }` in stage.yaml"));
  t.lock_memory = true;
  host.write("/proc/self/status", "Uid:\t1000\t1000\t1000\t1000\nGroups:\t998\nCapEff:\t0000000000000000\n");
  host.remove("/proc/self/limits");
  EXPECT_TRUE(unknown(check_memlock(host.files(), t)));
}

TEST(HostChecks, RealtimeGroup) {
  FakeHost host;
  host.write("/proc/self/status", "Uid:\t1000\t1000\t1000\t1000\nGroups:\t27\nCapEff:\t0\n");
  EXPECT_TRUE(is(check_realtime_group(host.files()), CheckStatus::warn, "adduser lab realtime"));
  host.write("/etc/group", "sudo:x:27:lab\n");
  EXPECT_TRUE(is(check_realtime_group(host.files()), CheckStatus::warn, "addgroup --system realtime"));
  host.remove("/etc/group");
  EXPECT_TRUE(unknown(check_realtime_group(host.files())));
}

TEST(HostChecks, RtThrottling) {
  FakeHost host;
  host.write("/proc/sys/kernel/sched_rt_runtime_us", "-1\n");
  EXPECT_TRUE(is(check_rt_throttling(host.files()), CheckStatus::pass));
  host.write("/proc/sys/kernel/sched_rt_runtime_us", "500000\n");
  EXPECT_TRUE(is(check_rt_throttling(host.files()), CheckStatus::warn, "sysctl -w kernel.sched_rt_runtime_us=950000"));
  host.write("/proc/sys/kernel/sched_rt_runtime_us", "0\n");
  EXPECT_TRUE(is(check_rt_throttling(host.files()), CheckStatus::fail, "sched_rt_runtime_us=950000"));
  host.write("/proc/sys/kernel/sched_rt_runtime_us", "lots\n");
  EXPECT_TRUE(unknown(check_rt_throttling(host.files())));
  host.remove("/proc/sys/kernel/sched_rt_runtime_us");
  EXPECT_TRUE(unknown(check_rt_throttling(host.files())));
}

TEST(HostChecks, IsolatedCpus) {
  FakeHost host;
  auto t = pipeline_on_cpu3();
  host.write("/sys/devices/system/cpu/isolated", "\n");
  EXPECT_TRUE(is(check_isolation(host.files(), t), CheckStatus::warn,
                 "add isolcpus=3 nohz_full=3 rcu_nocbs=3 to GRUB_CMDLINE_LINUX in /etc/default/grub, then "
                 "update-grub and reboot"));
  host.write("/sys/devices/system/cpu/isolated", "2\n");
  EXPECT_TRUE(is(check_isolation(host.files(), t), CheckStatus::warn, "cpu: 2 }` in stage.yaml"));
  host.write("/sys/devices/system/cpu/isolated", "3\n");
  host.write("/sys/devices/system/cpu/nohz_full", "\n");
  host.write("/proc/cmdline", "ro isolcpus=3\n");
  EXPECT_TRUE(is(check_isolation(host.files(), t), CheckStatus::warn, "add nohz_full=3 rcu_nocbs=3 to GRUB_CMDLINE_LINUX"));
  t.cpu = 7;  // written for a bigger host
  EXPECT_TRUE(is(check_isolation(host.files(), t), CheckStatus::fail, "cpu: 3 }` in stage.yaml"));
  t.cpu = -1;  // CPU 3 is isolated but the loop is not pinned to it
  EXPECT_TRUE(is(check_isolation(host.files(), t), CheckStatus::warn, "cpu: 3 }` in stage.yaml"));
  host.remove("/sys/devices/system/cpu/isolated");
  EXPECT_TRUE(unknown(check_isolation(host.files(), pipeline_on_cpu3())));
}

TEST(HostChecks, IrqAffinity) {
  FakeHost host;
  const auto t = pipeline_on_cpu3();
  host.write("/proc/irq/24/smp_affinity_list", "0-3\n");
  auto r = check_irq_affinity(host.files(), t);
  EXPECT_TRUE(is(r, CheckStatus::warn, "for f in /proc/irq/*/smp_affinity_list; do echo 0-2 > $f; done"));
  EXPECT_NE(r.found.find("IRQs 24 may run on CPU 3"), std::string::npos) << r.found;
  EXPECT_EQ(r.found.find("25"), std::string::npos) << r.found;
  host.write("/proc/irq/24/smp_affinity_list", "0\n");
  host.write("/proc/irq/default_smp_affinity", "f\n");
  r = check_irq_affinity(host.files(), t);
  EXPECT_TRUE(is(r, CheckStatus::warn, "echo 7 > /proc/irq/default_smp_affinity"));
  EXPECT_NE(r.fix.find("irqaffinity=0-2"), std::string::npos) << r.fix;
  host.remove("/proc/irq");
  EXPECT_TRUE(unknown(check_irq_affinity(host.files(), t)));
}

TEST(HostChecks, CpuGovernor) {
  FakeHost host;
  host.write("/sys/devices/system/cpu/cpu3/cpufreq/scaling_governor", "schedutil\n");
  const auto r = check_governor(host.files(), pipeline_on_cpu3());
  EXPECT_TRUE(is(r, CheckStatus::warn, "echo performance > /sys/devices/system/cpu/cpu3/cpufreq/scaling_governor"));
  EXPECT_NE(r.found.find("schedutil"), std::string::npos) << r.found;
  host.remove("/sys/devices/system/cpu/cpu3/cpufreq");
  EXPECT_TRUE(unknown(check_governor(host.files(), pipeline_on_cpu3())));
}

TEST(HostChecks, Smt) {
  FakeHost host;
  host.write("/sys/devices/system/cpu/smt/active", "1\n");
  EXPECT_TRUE(is(check_smt(host.files(), pipeline_on_cpu3()), CheckStatus::pass));  // CPU 3 has no sibling
  host.write("/sys/devices/system/cpu/cpu3/topology/thread_siblings_list", "1,3\n");
  const auto r = check_smt(host.files(), pipeline_on_cpu3());
  EXPECT_TRUE(is(r, CheckStatus::warn, "echo off > /sys/devices/system/cpu/smt/control"));
  EXPECT_NE(r.found.find("shares its core with CPU 1"), std::string::npos) << r.found;
  EXPECT_NE(r.fix.find("nosmt"), std::string::npos) << r.fix;
  host.remove("/sys/devices/system/cpu/smt");
  host.remove("/sys/devices/system/cpu/cpu3/topology");
  EXPECT_TRUE(unknown(check_smt(host.files(), pipeline_on_cpu3())));
}

TEST(HostChecks, CStates) {
  FakeHost host;
  const auto t = pipeline_on_cpu3();
  host.remove("/dev/cpu_dma_latency");  // lode run cannot hold the CPUs out of C6
  auto r = check_cstates(host.files(), t);
  EXPECT_TRUE(is(r, CheckStatus::warn, "processor.max_cstate=1 intel_idle.max_cstate=0"));
  EXPECT_NE(r.found.find("C6 133 us"), std::string::npos) << r.found;
  host.idle_state(2, "C6", 133, true);  // disabled
  EXPECT_TRUE(is(check_cstates(host.files(), t), CheckStatus::pass));
  host.remove("/sys/devices/system/cpu/cpu3/cpuidle");
  EXPECT_TRUE(unknown(check_cstates(host.files(), t)));
  host.write("/sys/devices/system/cpu/cpuidle/current_driver", "none\n");
  EXPECT_TRUE(is(check_cstates(host.files(), t), CheckStatus::pass));
}

TEST(HostChecks, TransparentHugepages) {
  FakeHost host;
  host.write("/sys/kernel/mm/transparent_hugepage/enabled", "[always] madvise never\n");
  EXPECT_TRUE(is(check_transparent_hugepages(host.files()), CheckStatus::warn,
                 "echo madvise > /sys/kernel/mm/transparent_hugepage/enabled"));
  host.remove("/sys/kernel/mm/transparent_hugepage");
  EXPECT_TRUE(unknown(check_transparent_hugepages(host.files())));
}

TEST(HostChecks, Swap) {
  FakeHost host;
  auto t = pipeline_on_cpu3();
  t.lock_memory = false;
  EXPECT_TRUE(is(check_swap(host.files(), t), CheckStatus::warn, "swapoff -a"));
  host.write("/proc/swaps", "Filename\t\t\t\tType\t\tSize\t\tUsed\t\tPriority\n");
  EXPECT_TRUE(is(check_swap(host.files(), t), CheckStatus::pass));
  host.remove("/proc/swaps");
  EXPECT_TRUE(unknown(check_swap(host.files(), t)));
}

TEST(HostChecks, AnEmptyRootIsUnknownEverywhereAndNeverFails) {
  FakeHost host;
  host.remove("/");
  fs::create_directories(host.root());
  const auto checks = run_host_checks(host.files(), pipeline_on_cpu3());
  for (const auto& c : checks) EXPECT_TRUE(unknown(c));
  EXPECT_TRUE(host_fit(checks));
}

TEST(HostChecks, FitMeansNoFailAndTheReportSaysEachFix) {
  FakeHost host;
  host.write("/sys/kernel/mm/transparent_hugepage/enabled", "[always] madvise never\n");
  auto checks = run_host_checks(host.files(), pipeline_on_cpu3());
  EXPECT_TRUE(host_fit(checks)) << "a WARN alone leaves the host fit";
  host.limits("0", "unlimited");
  checks = run_host_checks(host.files(), pipeline_on_cpu3());
  EXPECT_FALSE(host_fit(checks));
  const auto text = checks_text(checks);
  EXPECT_NE(text.find("FAIL  rtprio"), std::string::npos) << text;
  EXPECT_NE(text.find("WARN  transparent_hugepages"), std::string::npos) << text;
  EXPECT_NE(text.find("PASS  kernel"), std::string::npos) << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 12 + 2) << "one line per check, one fix line per WARN/FAIL:\n"
                                                                  << text;
  const auto json = checks_json(checks).dump(-1);
  EXPECT_NE(json.find(R"("name": "rtprio", "status": "FAIL")"), std::string::npos) << json;
  EXPECT_NE(json.find(R"("fix": "add '@realtime - rtprio 99')"), std::string::npos) << json;
}

TEST(HostChecks, CpuListsAndMasks) {
  EXPECT_EQ(parse_cpu_list("0-2,5,7-8"), (std::set<int>{0, 1, 2, 5, 7, 8}));
  EXPECT_EQ(parse_cpu_list(""), std::set<int>{});
  EXPECT_FALSE(parse_cpu_list("3-1"));
  EXPECT_FALSE(parse_cpu_list("x"));
  EXPECT_EQ(format_cpu_list({0, 1, 2, 5, 7, 8}), "0-2,5,7-8");
  EXPECT_EQ(parse_cpu_mask("00000000,00000013"), (std::set<int>{0, 1, 4}));
  EXPECT_EQ(format_cpu_mask({0, 1, 2}), "7");
  EXPECT_EQ(format_cpu_mask({4}), "10");
}

TEST(RtcheckLatency, Durations) {
  std::string why;
  EXPECT_EQ(parse_duration_ns("10s", why), 10'000'000'000);
  EXPECT_EQ(parse_duration_ns("500ms", why), 500'000'000);
  EXPECT_EQ(parse_duration_ns("2m", why), 120'000'000'000);
  EXPECT_EQ(parse_duration_ns("1.5", why), 1'500'000'000);
  EXPECT_EQ(parse_duration_ns("8h", why), 8 * 3'600'000'000'000);
  for (const char* bad : {"", "s", "10x", "-1s", "1e3", "0", "25h", "90000", "10 s"}) {
    EXPECT_FALSE(parse_duration_ns(bad, why)) << bad;
    EXPECT_NE(why.find(bad), std::string::npos) << why;
  }
}

TEST(RtcheckLatency, HeadroomAndSetupFindings) {
  LatencyReport r;
  r.plan.period_ns = 1'000'000;
  r.plan.priority = 80;
  r.plan.cpu = 3;
  r.sched_fifo = r.pinned = true;
  for (int i = 0; i < 1000; ++i) r.wakeups->record(5'000 + i);
  r.cycle_cost = std::make_unique<lode::Histogram>();
  for (int i = 0; i < 1000; ++i) r.cycle_cost->record(100'000);
  auto checks = latency_checks(r);
  ASSERT_EQ(checks.size(), 2U);
  EXPECT_TRUE(is(checks[0], CheckStatus::pass));
  EXPECT_TRUE(is(checks[1], CheckStatus::pass));
  EXPECT_NEAR(static_cast<double>(r.headroom_ns()), 1'000'000 - 5'999 - 100'000, 4'000);
  r.wakeups->record(950'000);  // one wake-up so late the cycle no longer fits
  r.sched_fifo = false;
  r.setup_warnings.push_back("SCHED_FIFO priority 80 refused (Operation not permitted)");
  checks = latency_checks(r);
  EXPECT_TRUE(is(checks[0], CheckStatus::warn, "rtprio"));
  EXPECT_NE(checks[0].found.find("refused"), std::string::npos) << checks[0].found;
  EXPECT_TRUE(is(checks[1], CheckStatus::fail, "rate_hz"));
  EXPECT_LT(r.headroom_ns(), 0);
}

TEST(RtcheckLatency, AHardwarePipelineIsNotRunAndTheHeadroomSaysSo) {
  LatencyReport r;
  r.plan.period_ns = 1'000'000;
  r.plan.priority = 0;
  for (int i = 0; i < 100; ++i) r.wakeups->record(10'000);
  r.plan.cycle_cost_skipped = "it drives hardware (realtime.clock: real)";
  const auto checks = latency_checks(r);
  EXPECT_TRUE(is(checks[1], CheckStatus::warn, "lode bench"));
  EXPECT_NE(checks[1].found.find("drives hardware"), std::string::npos) << checks[1].found;
  EXPECT_NE(latency_text(r).find("cycle cost: not measured (it drives hardware"), std::string::npos) << latency_text(r);
}

}  // namespace
