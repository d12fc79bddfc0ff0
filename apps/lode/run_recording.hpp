// The recording of `lode run --record FILE` and of the record_start/record_stop commands:
// every output of every cycle, copied on the RT thread into a tap only while a file is open,
// written to HDF5 off the RT thread at most record.flush_interval_s apart, with the exact
// configuration, the plugin files and (for a whole run) the output digest.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "lode/control.hpp"
#include "lode/event_log.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "lode/scheduler.hpp"
#include "lode/telemetry.hpp"
#include "output_digest.hpp"

namespace lode::cli {

class RunRecorder {
 public:
  /// Reads what produced the run (plugin files, io blocks) now, before the RT thread runs:
  /// describe() reads every block. `digest` (which outlives the recorder) gives the output
  /// digest and its algorithm when a whole run closes.
  RunRecorder(const Pipeline& pipeline, Scheduler& scheduler, EventLog& events, const OutputDigest& digest);
  ~RunRecorder();  ///< stops the writer (start_writer) if it runs
  RunRecorder(const RunRecorder&) = delete;
  RunRecorder& operator=(const RunRecorder&) = delete;

  /// The hook to add to the scheduler (RT side: copies the outputs while a file is open).
  [[nodiscard]] CycleHook& hook() { return tap_; }
  /// Opens FILE and starts recording at the next cycle; `expected_cycles` > 0 when the run's
  /// length is known (a replay), so the file is laid out for it (Recorder::expect_rows).
  Status open(const std::string& path, std::uint64_t expected_cycles = 0);
  /// What the files opened from now on say wrote them (their `source`): "lode run", "lode replay".
  void set_source(std::string source) { source_ = std::move(source); }
  void set_running(bool running) { running_.store(running); }
  /// On the simulated clock the cycles and on_idle() share one thread: from here until
  /// stop_writer() a thread of its own drains the tap and writes the file while the cycles
  /// run, so that a replay (RunServices starts it for `lode replay`) uses a second CPU for
  /// the recording instead of pausing its cycles for it.
  void start_writer();
  /// Wakes the writer for the last time and waits for it (what it left is drained by close()).
  void stop_writer();
  /// Tests: the writer wakes but drains nothing while held (a writer that falls behind).
  void hold_writer(bool held) { writer_held_.store(held); }
  /// Off the RT thread, between cycles: drain the tap, flush when the interval has passed.
  /// With the writer running, only wakes it; drains here (waiting for the writer) when the tap
  /// is more than half full, so that a simulated run stays lossless if the writer falls behind.
  void on_idle();
  /// Closes the file if one is open (end of run).
  Status close();
  /// record_start FILE / record_stop from the command service.
  ControlReply handle(const ControlRequest& request);
  /// Every recording closed so far: file, cycles, dropped, lost, error, complete.
  [[nodiscard]] Json finished() const;
  /// Blocks whose plugin is of kind io (their outputs are recorded as kind "raw").
  [[nodiscard]] const std::vector<std::string>& io_blocks() const { return io_blocks_; }

 private:
  /// A SignalTap over every output that copies only while a recording is open.
  class Tap final : public CycleHook {
   public:
    explicit Tap(std::vector<SignalRef> signals) : tap_(std::move(signals), 1 << 15) {}
    void after_cycle(const Tick& tick) noexcept override {
      if (open_.load(std::memory_order_acquire)) tap_.capture(tick.cycle, tick.time_ns);
    }
    SignalTap& tap() { return tap_; }
    std::atomic<bool>& open() { return open_; }

   private:
    SignalTap tap_;
    std::atomic<bool> open_{false};
  };

  // Each with mutex_ held.
  Status open_locked(const std::string& path, std::uint64_t expected_cycles = 0);
  void drain_locked();
  void flush_locked(bool force);
  void failed_locked(const std::string& why);
  Status close_locked();
  void write_until_stopped();

  const Pipeline& pipeline_;
  Scheduler& scheduler_;
  EventLog& events_;
  const RunStats& stats_;
  const OutputDigest& digest_;
  Tap tap_;
  std::string hostname_;
  std::vector<std::string> io_blocks_;  // their outputs are the raw inputs replay plays back
  std::string plugins_json_;            // plugin name -> .so path
  std::string blocks_json_;             // block -> plugin name
  std::atomic<bool> running_{false};

  // The recorder is used between cycles (main thread) and by the command thread: one mutex.
  mutable std::mutex mutex_;
  std::unique_ptr<record::Recorder> recorder_;
  std::string path_;
  std::string source_ = "lode run";
  std::vector<int> series_;  // per tapped signal
  std::vector<double> rows_;
  std::vector<std::uint64_t> row_cycles_;  // of the rows drained, for Recorder::append_rows
  std::vector<std::int64_t> row_stamps_;
  std::size_t event_cursor_ = 0;
  std::uint64_t recorded_cycles_ = 0;
  std::uint64_t flushed_cycles_ = 0;  // recorded_cycles_ at the last flush that succeeded
  std::chrono::steady_clock::time_point last_flush_ = std::chrono::steady_clock::now();
  Json finished_ = Json::array();
  bool from_start_ = false;  // opened before the first cycle
  std::optional<std::uint64_t> first_cycle_;

  // The writer of start_writer(): it waits on writer_wake_ with mutex_, and is woken by
  // on_idle() (writer_pending_) or stop_writer() (writer_stop_, set with mutex_ held).
  std::thread writer_;
  std::condition_variable writer_wake_;
  std::atomic<bool> writer_pending_{false};
  std::atomic<bool> writer_held_{false};
  bool writer_stop_ = false;
};

}  // namespace lode::cli
