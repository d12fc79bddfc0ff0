// Heap allocations of the real-time cycle, measured the way `lode run` runs it: the same
// Scheduler, and the same hooks around the pipeline (hot swap, command service, output digest,
// recorder tap, telemetry tap), with a recording open and telemetry publishing. Only the
// cycle thread's allocations between the first cycle's start and the last cycle's end are
// counted, less those of the scheduler's idle callback (the non-real-time side, which runs on
// the same thread under the simulated clock).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lode/event_log.hpp"

namespace lode::testing {

struct CycleAllocationRun {
  bool configured = false;      ///< the pipeline loaded, activated and the services started
  std::string error;            ///< why not
  std::uint64_t cycles = 0;     ///< cycles measured
  std::size_t allocations = 0;  ///< on the cycle thread, idle callbacks excluded
  bool faulted = false;
  std::string fault;
  std::vector<Event> events;    ///< everything posted, the health monitor's trips included
  std::uint64_t telemetry_published = 0;  ///< samples the DDS bridge published (0: no telemetry)
  std::uint64_t recorded_cycles = 0;      ///< cycles in the HDF5 recording (0: none)
};

struct CycleAllocationOptions {
  std::uint64_t cycles = 100000;
  bool real_clock = false;  ///< the scheduler's RT thread instead of back-to-back cycles
  bool telemetry = true;    ///< publish over DDS on a private domain, when the YAML has telemetry
  bool record = true;       ///< record every output to an HDF5 file in a temporary folder
};

/// Loads `yaml` (named `file` in messages), runs it and counts the cycle thread's allocations.
CycleAllocationRun measure_cycle_allocations(const std::string& yaml, const std::string& file,
                                             const CycleAllocationOptions& options = {});

}  // namespace lode::testing
