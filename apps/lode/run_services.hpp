// What `lode run` adds around the scheduler besides the status line: the command service
// (parameters, hot swap, promotion, recording) reachable over the local socket and over
// Fast DDS, the health monitor's events, telemetry, the local recorder (--record, and
// record_start/record_stop commands), and an output digest that proves two runs
// bit-identical.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"
#include "lode/dds/bridge.hpp"
#include "lode/sdk/status.hpp"
#include "output_digest.hpp"

namespace lode::cli {

/// On the simulated clock, the ops of one cycle in this many are timed (Scheduler): at 64 the
/// clock reads and histogram updates are 0.1 % of kawato_planar's cycle's instructions (0.8 %
/// at 8), and a 10 s run at 800 Hz still gives each block 125 samples for its median and
/// percentiles.
inline constexpr std::uint64_t kSimulatedTimingStride = 64;

struct RunServiceOptions {
  bool telemetry = true;             ///< start the DDS bridge when the YAML has `telemetry:`
  std::optional<int> domain;         ///< --domain overrides telemetry.domain
  std::string record_path;           ///< --record FILE: every output at full rate
  std::string record_source = "lode run";  ///< what the file says wrote it
  std::uint64_t record_rows = 0;      ///< cycles the run will have, when known (a replay): see Recorder::expect_rows
  int wait_subscribers = 0;          ///< --wait-subscribers N: start cycling once N readers matched
  double wait_s = 10.0;
  bool simulated = true;
  /// Serve commands on the local socket ($XDG_RUNTIME_DIR/lode/PIPELINE.sock). A second run
  /// of the same pipeline on this host is refused while the first one holds it.
  bool local_control = true;
  /// The output digest's hash: XXH3-64 for a run; a replay uses what its recording names.
  DigestAlgorithm digest = DigestAlgorithm::xxh3_64;
};

class RunServices {
 public:
  /// Prepare hooks and start the bridge; on error nothing is left running.
  static Expected<std::unique_ptr<RunServices>> start(Pipeline& pipeline, Scheduler& scheduler,
                                                      EventLog& events, const RunServiceOptions& options);
  ~RunServices();

  /// Before the first cycle: wait for subscribers if asked. False if they did not come.
  bool wait_for_subscribers();
  void set_running(bool running);
  /// Called from the scheduler's on_idle: drain the recorder; in simulated runs, hold the
  /// simulation while the telemetry rings are more than half full (no deadline to miss, so
  /// a simulated run is never lossy unless the publisher is stuck for seconds).
  void on_idle();
  /// End of run: stop recording, publish the rest, close the participant.
  void finish();
  /// {telemetry: {...}, recording: {...}, output_digest: "...", output_digest_algorithm: "..."}
  /// for the summary.
  [[nodiscard]] Json summary() const;
  /// True when the DDS publisher could not be stopped (stuck inside Fast DDS): the caller
  /// must leave with _exit() after writing its results, since destructors would hang.
  [[nodiscard]] bool dds_stuck() const { return dds_stuck_; }
  /// The 64-bit hash of the bits of every output of every cycle, as 16 hex digits.
  [[nodiscard]] std::string output_digest() const;
  /// Which hash output_digest() is (RunServiceOptions::digest).
  [[nodiscard]] DigestAlgorithm output_digest_algorithm() const;
  /// Blocks whose plugin is of kind io (their outputs are recorded as kind "raw").
  [[nodiscard]] const std::vector<std::string>& io_blocks() const;

  struct Impl;

 private:
  RunServices();
  std::unique_ptr<Impl> impl_;
  dds::BridgeStats last_bridge_stats_;
  bool dds_stuck_ = false;
};

/// The run itself, shared by `lode run` and `lode replay`: activate, the "start" event
/// (`start_text`), `on_active`, set_running, the cycles, deactivate (every output driven
/// safe), `after_run` (final drains, status line), the "stop" event, then services.finish()
/// (the recording is closed with its digest). An activation failure is returned as an error;
/// a fault during the run is in the RunResult.
Expected<RunResult> execute_run(Pipeline& pipeline, Scheduler& scheduler, EventLog& events, RunServices& services,
                                std::uint64_t cycles, const std::string& start_text,
                                const std::function<void()>& on_idle, const std::function<void()>& after_run = {},
                                const std::function<void()>& on_active = {});

/// Moves the calling thread, and so every thread it starts from now on (the log drain, the
/// local command server, Fast DDS's), off `rt_cpu`, where the pipeline's RT thread will be
/// pinned: a burst of telemetry or of commands then competes with the loop for no CPU. The
/// RT thread pins itself to `rt_cpu` afterwards (its own affinity). Nothing changes when the
/// process may run on `rt_cpu` alone (no other CPU to go to). Returns a warning, or "".
std::string keep_threads_off_cpu(int rt_cpu);

}  // namespace lode::cli
