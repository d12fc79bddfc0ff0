// io.replay: the outputs it declares are the recorded series of the chosen block (names,
// units, order), it plays them back bit for bit, and a recording it cannot play (missing
// file, no such block, a gap, series of different lengths) is a located configuration error.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <unistd.h>

#include "io_testing.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "lode/sdk/testing/harness.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"

namespace {

using lode::plugins::boards::testing::refusal_of;


std::string temp_file(const std::string& name) { return lode::testing::scratch_path(name); }

/// A recording of board "stage" (signals a/b in V, truth x in m) and an estimator output,
/// for cycles 0 .. n-1, skipping cycle `skip` in stage.signals when skip >= 0.
// `skip`: a cycle stage.signals has no row for (the recorder dropped it); with `skipped_by_loop`,
// no series has (the real-time loop skipped that period).
std::string make_recording(const std::string& name, std::size_t n, long skip = -1, std::size_t short_by = 0,
                           bool skipped_by_loop = false) {
  const std::string path = temp_file(name);
  auto r = lode::record::Recorder::create(path, "lode run");
  EXPECT_TRUE(r) << r.error();
  auto& rec = **r;
  auto series = [](std::string series_name, std::string kind, std::vector<std::string> names,
                   std::vector<std::string> units) {
    lode::record::SeriesInfo info;
    info.name = std::move(series_name);
    info.kind = std::move(kind);
    info.names = std::move(names);
    info.units = std::move(units);
    info.rate_hz = 800;
    info.pipeline_rate_hz = 800;
    return info;
  };
  const auto truth = series("stage.truth", "raw", {"x"}, {"m"});
  const auto signals = series("stage.signals", "raw", {"a", "b"}, {"V", "V"});
  const auto pose = series("kf.pose", "signal", {"x"}, {"m"});
  const int t = *rec.add_series(truth);
  const int s = *rec.add_series(signals);
  const int p = *rec.add_series(pose);
  for (std::size_t k = 0; k < n; ++k) {
    const auto stamp = static_cast<std::int64_t>(k) * 1250000;
    const double x = 1e-6 * static_cast<double>(k) + 1e-9 / 3.0;  // not a short binary fraction
    const double ab[2] = {std::sin(0.1 * static_cast<double>(k)), -0.0};
    if (skipped_by_loop && static_cast<long>(k) == skip) continue;
    if (k + short_by < n) rec.append(t, k, stamp, 0, &x);
    if (static_cast<long>(k) != skip) rec.append(s, k, stamp, 0, ab);
    rec.append(p, k, stamp, 0, &x);
  }
  EXPECT_TRUE(rec.close());
  return path;
}

TEST(IoReplay, DeclaresTheRecordedSeriesAndPlaysThemBitForBit) {
  const auto path = make_recording("ok.h5", 50);
  lode::testing::BlockHarness h("io.replay", "recording: " + path + "\nblock: stage", 800.0);
  h.feed("command", {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}});  // the original wiring stays valid
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());

  const auto& truth = h.output_elements("truth");
  ASSERT_EQ(truth.size(), 1u);
  EXPECT_EQ(truth[0].name, "x");
  EXPECT_EQ(truth[0].unit, "m");
  const auto& signals = h.output_elements("signals");
  ASSERT_EQ(signals.size(), 2u);
  EXPECT_EQ(signals[1].name, "b");
  EXPECT_EQ(signals[1].unit, "V");
  EXPECT_THROW(h.output("pose"), std::out_of_range);  // kf.pose belongs to another block

  auto rec = lode::record::read_recording(path);
  ASSERT_TRUE(rec);
  const auto& sig = rec->series[1];
  ASSERT_EQ(sig.info.name, "stage.signals");
  for (std::size_t k = 0; k < 50; ++k) {
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << "cycle " << k << ": " << h.block().fault_reason();
    EXPECT_EQ(std::memcmp(h.output("signals").data(), sig.values.data() + 2 * k, 2 * sizeof(double)), 0) << k;
    EXPECT_TRUE(std::signbit(h.output("signals")[1]));  // -0.0 stays -0.0
  }
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "end of recording");
}

// The raw series are what a replay reads; another block's series (an estimate replayed as a
// measurement) are read by name.
TEST(IoReplay, PlaysBackABlockWhoseSeriesAreNotRaw) {
  const auto path = make_recording("estimate.h5", 20);
  lode::testing::BlockHarness h("io.replay", "recording: " + path + "\nblock: kf", 800.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  EXPECT_THROW(h.output("signals"), std::out_of_range);  // stage.signals belongs to another block
  for (std::size_t k = 0; k < 20; ++k) {
    ASSERT_EQ(h.step(), lode::StepStatus::ok) << "cycle " << k << ": " << h.block().fault_reason();
    EXPECT_EQ(h.output("pose")[0], 1e-6 * static_cast<double>(k) + 1e-9 / 3.0) << k;
  }
}

TEST(IoReplay, AGapIsALocatedError) {
  const auto d = refusal_of("io.replay", "recording: " + make_recording("gap.h5", 40, 17) + "\nblock: stage", 800.0);
  EXPECT_NE(d.find("blocks.dut.recording"), std::string::npos) << d;
  EXPECT_NE(d.find("stage.signals"), std::string::npos) << d;
  EXPECT_NE(d.find("gap: row 17 is cycle 18, expected 17"), std::string::npos) << d;
}

// A period the real-time loop skipped after an overrun has no row in any series: no block ran
// it. The recorded cycles around it play back; the skipped one faults, naming why.
TEST(IoReplay, APeriodTheLoopSkippedIsPlayedAroundNotRefused) {
  const auto path = make_recording("skipped.h5", 40, 17, 0, true);
  lode::testing::BlockHarness h("io.replay", "recording: " + path + "\nblock: stage", 800.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  const lode::Json described = h.describe();
  ASSERT_NE(described.find("skipped_cycles"), nullptr);
  EXPECT_EQ(described.find("skipped_cycles")->as_number(), 1.0);
  for (std::uint64_t k : {0, 1, 2, 16, 18, 19, 39}) {
    ASSERT_EQ(h.step_at(k), lode::StepStatus::ok) << "cycle " << k << ": " << h.block().fault_reason();
    EXPECT_EQ(h.output("truth")[0], 1e-6 * static_cast<double>(k) + 1e-9 / 3.0) << k;
  }
  EXPECT_EQ(h.step_at(17), lode::StepStatus::fault);
  EXPECT_NE(std::string(h.block().fault_reason()).find("its real-time loop skipped it"), std::string::npos)
      << h.block().fault_reason();
  EXPECT_EQ(h.step_at(40), lode::StepStatus::fault);
  EXPECT_STREQ(h.block().fault_reason(), "end of recording");
}

TEST(IoReplay, SeriesOfDifferentLengthsAreALocatedError) {
  const auto d =
      refusal_of("io.replay", "recording: " + make_recording("short.h5", 40, -1, 3) + "\nblock: stage", 800.0);
  EXPECT_NE(d.find("blocks.dut.recording"), std::string::npos) << d;
  EXPECT_NE(d.find("has 40 samples, 'stage.truth' has 37"), std::string::npos) << d;
}

TEST(IoReplay, MissingBlockNamesTheRecordedBlocks) {
  const auto d = refusal_of("io.replay", "recording: " + make_recording("noblock.h5", 10) + "\nblock: board", 800.0);
  EXPECT_NE(d.find("blocks.dut.block"), std::string::npos) << d;
  EXPECT_NE(d.find("no series of block 'board' (blocks recorded: kf, stage)"), std::string::npos) << d;
}

TEST(IoReplay, DefaultBlockIsItsOwnName) {
  // The harness names the block "dut", which was not recorded.
  const auto d = refusal_of("io.replay", "recording: " + make_recording("default.h5", 10), 800.0);
  EXPECT_NE(d.find("no series of block 'dut'"), std::string::npos) << d;
}

TEST(IoReplay, MissingFileIsALocatedError) {
  const auto d = refusal_of("io.replay", "recording: /nonexistent/run.h5\nblock: stage", 800.0);
  EXPECT_NE(d.find("blocks.dut.recording"), std::string::npos) << d;
  EXPECT_NE(d.find("cannot read recording '/nonexistent/run.h5'"), std::string::npos) << d;
}

TEST(IoReplay, ACycleWithoutSampleFaults) {
  // A harness tick beyond the recording: fault, not stale data.
  const auto path = make_recording("one.h5", 1);
  lode::testing::BlockHarness h("io.replay", "recording: " + path + "\nblock: stage", 800.0);
  ASSERT_TRUE(h.configure()) << h.diagnostics();
  ASSERT_TRUE(h.activate());
  EXPECT_EQ(h.step(), lode::StepStatus::ok);
  EXPECT_EQ(h.step(), lode::StepStatus::fault);
}

}  // namespace
