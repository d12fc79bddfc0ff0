// The checks of `lode rtcheck`: is this host fit to run a pipeline's real-time loop, and what
// exactly to change when it is not. Each check reads only through HostFiles (one root
// directory), so the unit tests run every check on a fake /sys + /proc tree.
//
// What fails and what only warns: a FAIL is a finding that breaks the loop's timing or stops
// `lode run` from getting what the pipeline asks (no PREEMPT_RT kernel: millisecond wake-up
// spikes; an rtprio or memlock limit below what the pipeline needs: lode run falls back to
// normal scheduling or pageable memory; a pinned CPU that does not exist; RT tasks given no
// runtime at all). A WARN costs microseconds or depends on the load (a CPU not isolated, IRQs
// or a sibling hyperthread on the RT CPU, an on-demand governor, deep C-states, THP "always",
// swap without locked memory) or could not be checked (a file missing: "unknown").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "host_files.hpp"
#include "lode/sdk/json.hpp"

namespace lode::cli {

enum class CheckStatus { pass, warn, fail };
const char* status_name(CheckStatus s);

struct CheckResult {
  std::string name;    ///< stable, for scripts: "kernel", "rtprio", ...
  CheckStatus status = CheckStatus::pass;
  std::string found;   ///< what the host has
  std::string fix;     ///< the exact change, for every WARN and FAIL ("" for PASS)
};

/// What the loop will ask of the host: a pipeline's realtime section, or the defaults for
/// "this host in general".
struct HostTarget {
  std::string pipeline;      ///< the pipeline's name; "" without CONFIG
  std::string config_path;   ///< the file, for fix texts ("" without CONFIG)
  int priority = 80;         ///< SCHED_FIFO priority; the shipped pipelines use 80
  int cpu = -1;              ///< the RT CPU; -1 = not pinned
  bool lock_memory = true;
  std::int64_t period_ns = 1'000'000;
  [[nodiscard]] bool from_pipeline() const { return !pipeline.empty(); }
};

/// Every check, in the order the report prints them.
std::vector<CheckResult> run_host_checks(const HostFiles& files, const HostTarget& target);

/// Fit = no FAIL: `lode rtcheck` exits 0 then, else 1.
bool host_fit(const std::vector<CheckResult>& checks);

/// The checks one line each with the fix indented under every WARN and FAIL.
std::string checks_text(const std::vector<CheckResult>& checks);
/// checks[] of the --json output: {name, status, found, fix}.
Json checks_json(const std::vector<CheckResult>& checks);

// The single checks (run_host_checks calls each), for the tests.
CheckResult check_kernel(const HostFiles& files);
CheckResult check_rtprio(const HostFiles& files, const HostTarget& target);
CheckResult check_memlock(const HostFiles& files, const HostTarget& target);
CheckResult check_realtime_group(const HostFiles& files);
CheckResult check_rt_throttling(const HostFiles& files);
CheckResult check_isolation(const HostFiles& files, const HostTarget& target);
CheckResult check_irq_affinity(const HostFiles& files, const HostTarget& target);
CheckResult check_governor(const HostFiles& files, const HostTarget& target);
CheckResult check_smt(const HostFiles& files, const HostTarget& target);
CheckResult check_cstates(const HostFiles& files, const HostTarget& target);
CheckResult check_transparent_hugepages(const HostFiles& files);
CheckResult check_swap(const HostFiles& files, const HostTarget& target);

}  // namespace lode::cli
