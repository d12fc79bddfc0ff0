// The recording of a replay (lode replay, a simulated run of known length): written by a
// thread of its own while the cycles run, and still lossless when that thread falls behind
// (the cycle thread then drains the tap itself before it can overflow).
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

#include "config_text.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "lode/scheduler.hpp"
#include "output_digest.hpp"
#include "run_recording.hpp"

namespace {

namespace fs = std::filesystem;

struct RecordedRun {
  std::uint64_t cycles = 0, recorded = 0, dropped = 0;
  bool complete = false;
  std::string digest, recorded_digest;
};

/// kawato_planar on the simulated clock for `cycles`, recorded with the writer thread running
/// (held: draining nothing) as RunServices runs it.
RecordedRun run_recorded(std::uint64_t cycles, bool hold_writer) {
  RecordedRun out;
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(lode::test::read_config("kawato_planar.yaml"), "kawato_planar.yaml", registry,
                                     diag);
  EXPECT_TRUE(p) << diag.format();
  if (!p) return out;
  const fs::path file = fs::temp_directory_path() / ("lode_sim_recording_" + std::to_string(::getpid()) + ".h5");
  lode::SimulatedClock clock;
  lode::EventLog events;
  lode::Scheduler sched(*p, clock, events);
  lode::cli::OutputDigest digest(p->signals(), lode::cli::DigestAlgorithm::xxh3_64);
  lode::cli::RunRecorder recorder(*p, sched, events, digest);
  sched.add_hook(&digest);
  sched.add_hook(&recorder.hook());
  EXPECT_TRUE(recorder.open(file.string(), cycles).is_ok());
  EXPECT_TRUE(p->activate().is_ok());
  recorder.set_running(true);
  recorder.start_writer();
  recorder.hold_writer(hold_writer);
  std::atomic<bool> stop{false};
  const auto result = sched.run(cycles, stop, [&] { recorder.on_idle(); });
  EXPECT_FALSE(result.faulted) << result.fault;
  recorder.set_running(false);
  recorder.stop_writer();
  p->deactivate();
  EXPECT_TRUE(recorder.close().is_ok());
  out.cycles = sched.stats().cycles.load();
  out.digest = digest.text();
  const lode::Json finished = recorder.finished();
  if (!finished.elements().empty()) {
    const lode::Json& f = finished.elements()[0];
    out.recorded = static_cast<std::uint64_t>(f.find("cycles")->as_number());
    out.dropped = static_cast<std::uint64_t>(f.find("dropped")->as_number());
    out.complete = f.find("complete")->as_bool();
  }
  if (auto rec = lode::record::read_recording(file.string())) {
    out.recorded_digest = rec->text_attributes["output_digest"];
    for (const auto& s : rec->series) EXPECT_EQ(s.rows(), cycles) << s.info.name;
  }
  fs::remove(file);
  return out;
}

/// Every one of the run's cycles in the file, none dropped, and the file's digest the run's.
void expect_every_cycle_recorded(const RecordedRun& run, std::uint64_t cycles) {
  EXPECT_EQ(run.cycles, cycles);
  EXPECT_EQ(run.recorded, cycles);
  EXPECT_EQ(run.dropped, 0u);
  EXPECT_TRUE(run.complete);
  EXPECT_EQ(run.recorded_digest, run.digest);
}

TEST(SimulatedRecording, TheWriterThreadRecordsEveryCycle) {
  const auto run = run_recorded(50000, false);
  expect_every_cycle_recorded(run, 50000);
}

// More cycles than the tap holds (32768): without the cycle thread's own drains, a writer that
// drains nothing loses every cycle after the tap fills.
TEST(SimulatedRecording, AWriterThatFallsBehindLosesNoCycle) {
  const auto run = run_recorded(50000, true);
  expect_every_cycle_recorded(run, 50000);
}

}  // namespace
