// lodestone::record: HDF5 recordings round-trip bit for bit, count lost samples, survive a
// crash after flush(), and write the files tests/record/read_recording.py reads with h5py.
#include "lode/record/hdf5_recorder.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <malloc.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <thread>

namespace lode::record {
namespace {

namespace fs = std::filesystem;

// The process's own scratch folder, removed when it exits (every test leaves nothing behind,
// whether it removes its files itself or stops at a failed assertion first).
using lode::testing::scratch_path;

std::uint64_t bits(double value) { return std::bit_cast<std::uint64_t>(value); }

/// Doubles with arbitrary bit patterns (NaN payloads, signalling NaNs, subnormals, ±Inf,
/// -0.0): a round trip must preserve every bit, not just compare equal.
class AwkwardDoubles {
 public:
  double next() {
    const std::uint64_t pick = engine_() % 16;
    if (pick == 0) return std::bit_cast<double>(engine_());  // any pattern
    // NaN with a payload, signalling or quiet, then a negative quiet NaN with a payload.
    if (pick == 1) return std::bit_cast<double>(0x7FF0000000000000ULL | (engine_() & 0x000FFFFFFFFFFFFFULL) | 1ULL);
    if (pick == 2) return std::bit_cast<double>(0xFFF8000000000000ULL | (engine_() & 0x0007FFFFFFFFFFFFULL));
    if (pick == 3)
      return (engine_() & 1) ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity();
    if (pick == 4) return std::bit_cast<double>(engine_() & 0x000FFFFFFFFFFFFFULL);  // subnormal
    if (pick == 5) return -0.0;
    return std::uniform_real_distribution<double>(-1e3, 1e3)(engine_);
  }

 private:
  std::mt19937_64 engine_{20261122};
};

void expect_same_info(const SeriesInfo& expected, const SeriesInfo& actual) {
  EXPECT_EQ(actual.name, expected.name);
  EXPECT_EQ(actual.topic, expected.topic);
  EXPECT_EQ(actual.kind, expected.kind);
  EXPECT_EQ(actual.names, expected.names);
  EXPECT_EQ(actual.units, expected.units);
  EXPECT_EQ(bits(actual.rate_hz), bits(expected.rate_hz));
  EXPECT_EQ(bits(actual.pipeline_rate_hz), bits(expected.pipeline_rate_hz));
  EXPECT_EQ(actual.decimation, expected.decimation);
}

struct ExpectedSeries {
  SeriesInfo info;
  std::vector<std::uint64_t> cycle;
  std::vector<std::int64_t> stamp_ns, captured_ns;
  std::vector<double> values;
};

void expect_same_rows(const ExpectedSeries& expected, const SeriesData& actual, std::size_t rows) {
  ASSERT_GE(actual.rows(), rows) << actual.info.name;
  ASSERT_GE(expected.cycle.size(), rows);
  const std::size_t width = expected.info.names.size();
  std::size_t mismatches = 0;
  for (std::size_t row = 0; row < rows; ++row) {
    mismatches += actual.cycle[row] != expected.cycle[row];
    mismatches += actual.stamp_ns[row] != expected.stamp_ns[row];
    mismatches += actual.captured_ns[row] != expected.captured_ns[row];
    for (std::size_t v = 0; v < width; ++v) {
      mismatches += bits(actual.values[row * width + v]) != bits(expected.values[row * width + v]);
    }
  }
  EXPECT_EQ(mismatches, 0U) << actual.info.name;
}

TEST(Hdf5RecorderTest, RoundTripIsBitIdentical) {
  const std::string path = scratch_path("round_trip.h5");
  auto recorder = Recorder::create(path, "lode record");
  ASSERT_TRUE(recorder) << recorder.error();
  Recorder& rec = **recorder;

  std::string config;  // larger than HDF5's 64 KiB compact attribute limit
  while (config.size() < 200'000) config += "pipeline: {blocks: [glsdc, plant, lqr]}  # θ in rad\n";
  rec.set_attribute("pipeline", "kawato_planar");
  rec.set_attribute("config", config);
  rec.set_attribute("host", "first value, replaced below");
  rec.set_attribute("host", "rt-host-1");
  rec.set_attribute("base_rate_hz", 1000.0);

  std::vector<ExpectedSeries> expected(3);
  expected[0].info = {
      "glsdc.pose", "lode/kawato_planar/glsdc/pose", "signal", {"x", "y", "θ"}, {"m", "m", "rad"}, 1000.0, 1000.0, 1};
  // Element names that collide with a time column or are not valid link names get a prefix.
  expected[1].info = {"plant.gap", "", "raw", {"time_s"}, {"V"}, 100.0, 1000.0, 10};
  expected[2].info = {"lqr.state",
                      "lode/kawato_planar/lqr/state",
                      "state",
                      {"a/b", "", ".", "q3", "q4", "q5"},
                      {"m", "m/s", "rad", "rad/s", "A", "N"},
                      250.0,
                      1000.0,
                      4};
  std::vector<int> handles(3, -1);
  for (int s = 0; s < 2; ++s) {
    auto handle = rec.add_series(expected[static_cast<std::size_t>(s)].info);
    ASSERT_TRUE(handle) << handle.error();
    handles[static_cast<std::size_t>(s)] = *handle;
  }

  AwkwardDoubles doubles;
  std::vector<Recording::Ev> events;
  constexpr std::uint64_t kCycles = 80'000;
  constexpr std::uint64_t kThirdSeriesFrom = 20'000;  // added after the others have samples
  std::size_t total = 0;
  for (std::uint64_t cycle = 0; cycle < kCycles; ++cycle) {
    if (cycle == kThirdSeriesFrom) {
      auto handle = rec.add_series(expected[2].info);
      ASSERT_TRUE(handle) << handle.error();
      handles[2] = *handle;
    }
    for (std::size_t s = 0; s < 3; ++s) {
      ExpectedSeries& series = expected[s];
      if (handles[s] < 0 || cycle % series.info.decimation != 0) continue;
      const auto stamp = static_cast<std::int64_t>(cycle) * 1'000'000;
      const auto captured = 5'000'000'000'000LL + stamp + static_cast<std::int64_t>(cycle % 7) * 1000;
      const std::size_t first = series.values.size();
      for (std::size_t v = 0; v < series.info.names.size(); ++v) series.values.push_back(doubles.next());
      series.cycle.push_back(cycle);
      series.stamp_ns.push_back(stamp);
      series.captured_ns.push_back(captured);
      rec.append(handles[s], cycle, stamp, captured, series.values.data() + first);
      ++total;
    }
    if (cycle % 97 == 0) {
      events.push_back({cycle, static_cast<std::int64_t>(cycle) * 1'000'000, cycle % 2 ? "fault" : "warning",
                        "cycle " + std::to_string(cycle) + ": gap sensor out of range — θ ≥ 0.1 rad"});
      rec.add_event(events.back().cycle, events.back().stamp_ns, events.back().kind, events.back().text);
    }
    if (cycle % 12'345 == 12'344) {  // not chunk-aligned
      ASSERT_TRUE(rec.flush()) << "flush at cycle " << cycle;
    }
  }
  EXPECT_GE(total, 100'000U);
  for (std::size_t s = 0; s < 3; ++s) {
    EXPECT_EQ(rec.samples(handles[s]), expected[s].cycle.size());
    EXPECT_EQ(rec.gaps(handles[s]), 0U);
  }
  const Status closed = rec.close();
  ASSERT_TRUE(closed) << closed.message();

  auto recording = read_recording(path);
  ASSERT_TRUE(recording) << recording.error();
  EXPECT_TRUE(recording->warnings.empty());
  EXPECT_EQ(recording->text_attributes["format"], "lodestone-recording");
  EXPECT_EQ(recording->number_attributes["format_version"], 1.0);
  EXPECT_EQ(recording->text_attributes["source"], "lode record");
  EXPECT_EQ(recording->text_attributes["created_utc"].size(), std::string("2026-11-22T02:52:12Z").size());
  EXPECT_EQ(recording->text_attributes["pipeline"], "kawato_planar");
  EXPECT_EQ(recording->text_attributes["host"], "rt-host-1");
  EXPECT_EQ(recording->text_attributes["config"], config);
  EXPECT_EQ(recording->number_attributes["base_rate_hz"], 1000.0);

  ASSERT_EQ(recording->series.size(), 3U);
  for (std::size_t s = 0; s < 3; ++s) {
    const SeriesData& actual = recording->series[s];
    expect_same_info(expected[s].info, actual.info);
    EXPECT_EQ(actual.rows(), expected[s].cycle.size());
    EXPECT_EQ(actual.values.size(), expected[s].values.size());
    expect_same_rows(expected[s], actual, expected[s].cycle.size());
    EXPECT_EQ(actual.gaps, 0U);
  }
  ASSERT_EQ(recording->events.size(), events.size());
  for (std::size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(recording->events[i].cycle, events[i].cycle);
    EXPECT_EQ(recording->events[i].stamp_ns, events[i].stamp_ns);
    EXPECT_EQ(recording->events[i].kind, events[i].kind);
    EXPECT_EQ(recording->events[i].text, events[i].text);
  }
  EXPECT_EQ(dataset_name_for("time_s", 0), "value_time_s");
  EXPECT_EQ(dataset_name_for("a/b", 0), "value_a_b");
  EXPECT_EQ(dataset_name_for("", 1), "value_1");
  EXPECT_EQ(dataset_name_for(".", 2), "value_.");
  EXPECT_EQ(dataset_name_for("θ", 2), "θ");
}

// A replay knows its length: the datasets are made at that size and filled in bulk. What the
// file holds must not depend on it: rows appended in bulk read back bit for bit, a run that
// ends early leaves no fill rows behind, and one that runs longer extends the datasets.
// What is most often given where a recording goes is said in the user's words, not HDF5's
// ("unable to open file: name = ..., errno = 2"; "file signature not found").
TEST(Hdf5RecorderTest, WhatIsNotARecordingIsSaidPlainly) {
  const auto error_of = [](const std::string& path) {
    auto r = lode::record::read_recording(path);
    return r ? std::string("read") : r.error();
  };
  const std::string missing = scratch_path("missing.h5");
  EXPECT_EQ(error_of(missing), "recording '" + missing + "': no such file");
  const std::string folder = scratch_path("folder.h5");
  std::filesystem::create_directories(folder);
  EXPECT_EQ(error_of(folder), "recording '" + folder + "': a directory, not a recording");
  const std::string empty = scratch_path("empty.h5");
  std::ofstream(empty).close();
  EXPECT_EQ(error_of(empty), "recording '" + empty + "': an empty file, not a recording");
  const std::string yaml = scratch_path("pipeline.yaml");
  std::ofstream(yaml) << "pipeline: x\nrate_hz: 800\n";
  EXPECT_NE(error_of(yaml).find("recording '" + yaml + "': not an HDF5 file"), std::string::npos) << error_of(yaml);
}

// A recording of unknown length (lode record, lode run --record) keeps the chunks it is still
// filling in memory, not every chunk it wrote. With HDF5's default cache of 1 MiB per column,
// each column held its last 160 s of finished 800 Hz chunks: these 40 columns took 64 MB of
// heap after 300 s of rows, and settled at 73.5 MB (two chunks per column: 7 MB, settling
// at 16.5 MB).
TEST(Hdf5RecorderTest, HeapHoldsTheChunksBeingFilledNotTheFinishedOnes) {
  const auto heap_bytes = [] { return static_cast<double>(mallinfo2().uordblks); };
  const double heap_before = heap_bytes();
  const std::string path = scratch_path("long_recording.h5");
  auto recorder = Recorder::create(path, "lode record");
  ASSERT_TRUE(recorder) << recorder.error();
  Recorder& rec = **recorder;
  constexpr std::size_t kSeries = 4, kValues = 9, kRate = 800;
  std::vector<int> handles;
  for (std::size_t s = 0; s < kSeries; ++s) {
    SeriesInfo info{"s" + std::to_string(s), "", "signal", {}, {}, double{kRate}, double{kRate}, 1};
    for (std::size_t v = 0; v < kValues; ++v) {
      info.names.push_back("v" + std::to_string(v));
      info.units.push_back("m");
    }
    auto handle = rec.add_series(info);
    ASSERT_TRUE(handle) << handle.error();
    handles.push_back(*handle);
  }
  std::vector<std::uint64_t> cycles(kRate);
  std::vector<std::int64_t> stamps(kRate);
  std::vector<double> values(kRate * kValues, 0.5);
  // One second of rows at a time, flushed as lode record flushes them.
  for (std::uint64_t second = 0; second < 300; ++second) {
    for (std::uint64_t k = 0; k < kRate; ++k) {
      cycles[k] = second * kRate + k;
      stamps[k] = static_cast<std::int64_t>(cycles[k]) * 1'250'000;
    }
    for (int h : handles) rec.append_rows(h, kRate, cycles.data(), stamps.data(), values.data(), kValues);
    ASSERT_TRUE(rec.flush());
  }
  const double held_mb = (heap_bytes() - heap_before) / 1e6;
  ASSERT_TRUE(rec.close());
  std::filesystem::remove(path);
  EXPECT_LT(held_mb, 20.0) << "an open recording of 300 s holds " << held_mb << " MB of heap";
}

TEST(Hdf5RecorderTest, KnownLengthBulkRowsReadBackExactly) {
  for (const std::uint64_t appended : {std::uint64_t{40'000}, std::uint64_t{25'001}, std::uint64_t{41'000}}) {
    const std::string path = scratch_path("known_length_" + std::to_string(appended) + ".h5");
    {
      auto recorder = Recorder::create(path, "lode run");
      ASSERT_TRUE(recorder) << recorder.error();
      Recorder& rec = **recorder;
      rec.expect_rows(40'000);
      const SeriesInfo info{"kf.pose", "", "signal", {"x", "y", "theta_z"}, {"m", "m", "rad"}, 800.0, 800.0, 1};
      auto handle = rec.add_series(info);
      ASSERT_TRUE(handle) << handle.error();
      // Rows as a tap drains them: a cycle, a time and the values, several series per row.
      constexpr std::size_t kStride = 5;
      AwkwardDoubles doubles;
      std::vector<double> rows(appended * kStride);
      std::vector<std::uint64_t> cycles(appended);
      std::vector<std::int64_t> stamps(appended);
      for (std::uint64_t r = 0; r < appended; ++r) {
        cycles[r] = r;
        stamps[r] = static_cast<std::int64_t>(r) * 1'250'000;
        for (std::size_t v = 0; v < kStride; ++v) rows[r * kStride + v] = doubles.next();
      }
      // In uneven batches, as the idle drain delivers them, across chunk boundaries.
      for (std::size_t done = 0, batch = 1000; done < appended; done += batch, batch = batch * 3 % 7919 + 1) {
        const std::size_t n = std::min<std::size_t>(batch, appended - done);
        rec.append_rows(*handle, n, cycles.data() + done, stamps.data() + done, rows.data() + done * kStride + 2,
                        kStride);
      }
      ASSERT_TRUE(rec.close()) << path;
      auto back = read_recording(path);
      ASSERT_TRUE(back) << back.error();
      ASSERT_EQ(back->series.size(), 1U);
      const SeriesData& s = back->series.front();
      EXPECT_TRUE(back->warnings.empty()) << back->warnings.front();
      ASSERT_EQ(s.rows(), appended) << "rows in " << path << " after expect_rows(40000)";
      std::size_t mismatches = 0;
      for (std::uint64_t r = 0; r < appended; ++r) {
        mismatches += s.cycle[r] != cycles[r] || s.stamp_ns[r] != stamps[r] || s.captured_ns[r] != 0;
        for (std::size_t v = 0; v < 3; ++v) mismatches += bits(s.values[r * 3 + v]) != bits(rows[r * kStride + 2 + v]);
      }
      EXPECT_EQ(mismatches, 0U) << path;
      EXPECT_EQ(s.gaps, 0U);
      EXPECT_EQ(s.out_of_order, 0U);
    }
  }
}

// lode replay and its io.replay blocks read one recording: the second read is the first's
// copy while that is held, and a file rewritten in between is read again.
TEST(Hdf5RecorderTest, SharedReadIsOneCopyUntilTheFileChanges) {
  const std::string path = scratch_path("shared.h5");
  auto write = [&](double value) {
    auto recorder = Recorder::create(path, "lode run");
    ASSERT_TRUE(recorder) << recorder.error();
    auto handle = (*recorder)->add_series({"stage.counts", "", "raw", {"x"}, {""}, 800.0, 800.0, 1});
    ASSERT_TRUE(handle) << handle.error();
    for (std::uint64_t cycle = 0; cycle < 100; ++cycle) (*recorder)->append(*handle, cycle, 0, 0, &value);
    ASSERT_TRUE((*recorder)->close());
  };
  write(1.0);
  auto first = read_recording_shared(path);
  ASSERT_TRUE(first) << first.error();
  auto again = read_recording_shared(path);
  ASSERT_TRUE(again) << again.error();
  EXPECT_EQ(first->get(), again->get()) << "the second read of an unchanged file is not the held copy";
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // a later modification time
  write(2.0);
  auto rewritten = read_recording_shared(path);
  ASSERT_TRUE(rewritten) << rewritten.error();
  EXPECT_NE(first->get(), rewritten->get()) << "a rewritten file was not read again";
  ASSERT_EQ((*rewritten)->series.size(), 1U);
  EXPECT_EQ((*rewritten)->series.front().values.front(), 2.0);
  EXPECT_FALSE(read_recording_shared(scratch_path("missing.h5"))) << "a missing file must be an error";
}

// A replay reads a recording's raw inputs, io.replay one block's series, the bit-for-bit check
// one series at a time: each gets those series whole and the names of the rest, the memory
// check counts only what is read, and shared copies of different selections are different.
TEST(Hdf5RecorderTest, ASelectionReadsItsSeriesAndNamesTheRest) {
  const std::string path = scratch_path("selection.h5");
  {
    auto recorder = Recorder::create(path, "lode run");
    ASSERT_TRUE(recorder) << recorder.error();
    auto counts = (*recorder)->add_series({"stage.counts", "", "raw", {"a", "b"}, {"", ""}, 800.0, 800.0, 1});
    auto pose = (*recorder)->add_series({"kf.pose", "", "signal", {"x", "y", "z"}, {"m", "m", "m"}, 800.0, 800.0, 1});
    auto truth = (*recorder)->add_series({"stage.truth", "", "raw", {"x"}, {"m"}, 800.0, 800.0, 1});
    ASSERT_TRUE(counts && pose && truth);
    for (std::uint64_t cycle = 0; cycle < 1000; ++cycle) {
      const double v[3] = {static_cast<double>(cycle), 0.5, -1.0};
      (*recorder)->append(*counts, cycle, 0, 0, v);
      (*recorder)->append(*pose, cycle, 0, 0, v);
      (*recorder)->append(*truth, cycle, 0, 0, v);
    }
    ASSERT_TRUE((*recorder)->close());
  }
  const auto names = [](const Recording& r) {
    std::vector<std::string> out;
    for (const auto& s : r.series) out.push_back(s.info.name);
    return out;
  };
  auto raw = read_recording(path, SeriesSelection::raw());
  ASSERT_TRUE(raw) << raw.error();
  EXPECT_EQ(names(*raw), (std::vector<std::string>{"stage.counts", "stage.truth"}));
  EXPECT_EQ(raw->series_not_read, std::vector<std::string>{"kf.pose"});
  ASSERT_EQ(raw->series.front().rows(), 1000U);
  EXPECT_EQ(raw->series.front().values[2 * 999], 999.0);

  auto block = read_recording(path, SeriesSelection::block("kf"));
  ASSERT_TRUE(block) << block.error();
  EXPECT_EQ(names(*block), std::vector<std::string>{"kf.pose"});
  EXPECT_EQ(block->series_not_read, (std::vector<std::string>{"stage.counts", "stage.truth"}));
  auto one = read_recording(path, SeriesSelection::one("stage.truth"));
  ASSERT_TRUE(one) << one.error();
  EXPECT_EQ(names(*one), std::vector<std::string>{"stage.truth"});
  EXPECT_EQ(names(*read_recording(path)), (std::vector<std::string>{"stage.counts", "kf.pose", "stage.truth"}));

  // Rows x (3 time columns + values), plus the largest series' values once more.
  auto raw_cost = read_cost(path, SeriesSelection::raw());
  auto all_cost = read_cost(path, SeriesSelection::all());
  ASSERT_TRUE(raw_cost && all_cost);
  EXPECT_EQ(raw_cost->bytes, 1000U * 8 * ((3 + 2) + (3 + 1)) + 1000U * 8 * 2);
  EXPECT_EQ(all_cost->bytes, 1000U * 8 * ((3 + 2) + (3 + 3) + (3 + 1)) + 1000U * 8 * 3);
  EXPECT_EQ(all_cost->largest_series, 1000U * 8 * (6 + 3));
  EXPECT_EQ(all_cost->rows, 1000U);

  auto shared_raw = read_recording_shared(path, SeriesSelection::raw());
  auto shared_raw_again = read_recording_shared(path, SeriesSelection::raw());
  auto shared_all = read_recording_shared(path);
  ASSERT_TRUE(shared_raw && shared_raw_again && shared_all);
  EXPECT_EQ(shared_raw->get(), shared_raw_again->get());
  EXPECT_NE(shared_raw->get(), shared_all->get()) << "the raw selection was handed the whole recording's copy";
  EXPECT_EQ((*shared_all)->series.size(), 3U);

  // Series by series from one open file.
  auto reader = SeriesReader::open(path);
  ASSERT_TRUE(reader) << reader.error();
  EXPECT_EQ((*reader)->names(), (std::vector<std::string>{"stage.counts", "kf.pose", "stage.truth"}));
  std::vector<std::string> warnings;
  auto pose = (*reader)->read("kf.pose", warnings);
  ASSERT_TRUE(pose) << pose.error();
  EXPECT_EQ(pose->width(), 3U);
  ASSERT_EQ(pose->rows(), 1000U);
  EXPECT_EQ(pose->values[3 * 999], 999.0);
  EXPECT_EQ(pose->values[3 * 999 + 2], -1.0);
  EXPECT_TRUE(warnings.empty());
  EXPECT_FALSE((*reader)->read("kf.velocity", warnings)) << "a series the file does not have";
  EXPECT_FALSE(SeriesReader::open(scratch_path("missing.h5")));
}

// A recording written over a plain file replaces it with a new file (ext4 writes a file that
// was truncated and rewritten out to disk inside its close); over a symbolic link or a file
// with a second name, the file itself is rewritten, as a truncation did.
TEST(Hdf5RecorderTest, CreateReplacesAPlainFileAndRewritesALinkedOne) {
  auto write = [](const std::string& path, double value) {
    auto recorder = Recorder::create(path, "lode run");
    ASSERT_TRUE(recorder) << recorder.error();
    auto handle = (*recorder)->add_series({"s", "", "signal", {"v"}, {"m"}, 800.0, 800.0, 1});
    ASSERT_TRUE(handle) << handle.error();
    (*recorder)->append(*handle, 0, 0, 0, &value);
    ASSERT_TRUE((*recorder)->close());
  };
  auto value_in = [](const std::string& path) {
    auto back = read_recording(path);
    return back && !back->series.empty() && !back->series[0].values.empty() ? back->series[0].values[0] : NAN;
  };
  auto inode = [](const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 ? st.st_ino : 0;
  };
  const std::string plain = scratch_path("replaced.h5");
  write(plain, 1.0);
  const auto first = inode(plain);
  std::ifstream held(plain);  // a reader that still has the old file open keeps it
  write(plain, 2.0);
  EXPECT_EQ(value_in(plain), 2.0);
  EXPECT_NE(inode(plain), first) << "the file was truncated and rewritten, not replaced";

  const std::string target = scratch_path("target.h5"), link = scratch_path("link.h5"), second = scratch_path("second.h5");
  write(target, 1.0);
  fs::remove(link);
  fs::create_symlink(target, link);
  write(link, 3.0);
  EXPECT_TRUE(fs::is_symlink(link)) << "the symbolic link was replaced by a file";
  EXPECT_EQ(value_in(target), 3.0) << "the link's target was not rewritten";
  fs::remove(second);
  fs::create_hard_link(target, second);
  write(second, 4.0);
  EXPECT_EQ(fs::hard_link_count(target), 2U) << "the second name was replaced by a file of its own";
  EXPECT_EQ(value_in(target), 4.0);
}

TEST(Hdf5RecorderTest, SkippedCyclesAreCountedAsGaps) {
  const std::string path = scratch_path("gaps.h5");
  auto recorder = Recorder::create(path, "lode run");
  ASSERT_TRUE(recorder) << recorder.error();
  auto series = (*recorder)->add_series({"ctrl.u", "", "signal", {"u"}, {"V"}, 500.0, 1000.0, 2});
  ASSERT_TRUE(series) << series.error();
  const double value = 1.0;
  // decimation 2: 6 missing (1 gap), 12..18 missing (4 gaps), 21 after 20 is early but not a
  // gap, 23 after 21 is on time, 23 again is out of order.
  for (std::uint64_t cycle : {0, 2, 4, 8, 10, 20, 21, 23, 23, 27}) {
    (*recorder)->append(*series, cycle, static_cast<std::int64_t>(cycle) * 1'000'000, 0, &value);
  }
  EXPECT_EQ((*recorder)->samples(*series), 10U);
  EXPECT_EQ((*recorder)->gaps(*series), 1U + 4U + 1U);  // + 25 missing before 27
  EXPECT_EQ((*recorder)->out_of_order(*series), 1U);
  ASSERT_TRUE((*recorder)->close());

  auto recording = read_recording(path);
  ASSERT_TRUE(recording) << recording.error();
  ASSERT_EQ(recording->series.size(), 1U);
  EXPECT_EQ(recording->series[0].gaps, 6U);
  EXPECT_EQ(recording->series[0].out_of_order, 1U);
  EXPECT_EQ(recording->series[0].rows(), 10U);
}

TEST(Hdf5RecorderTest, DestructorWritesEverythingAndCloses) {
  const std::string path = scratch_path("destructor.h5");
  {
    auto recorder = Recorder::create(path, "lode record");
    ASSERT_TRUE(recorder) << recorder.error();
    auto series = (*recorder)->add_series({"s", "", "signal", {"v"}, {"m"}, 1000.0, 1000.0, 1});
    ASSERT_TRUE(series) << series.error();
    for (std::uint64_t cycle = 0; cycle < 1500; ++cycle) {  // 1 whole chunk of 1000 rows + 500 buffered
      const double value = static_cast<double>(cycle);
      (*recorder)->append(*series, cycle, 0, 0, &value);
    }
    (*recorder)->add_event(3, 0, "stop", "end");
  }
  auto recording = read_recording(path);
  ASSERT_TRUE(recording) << recording.error();
  ASSERT_EQ(recording->series.size(), 1U);
  EXPECT_EQ(recording->series[0].rows(), 1500U);
  EXPECT_EQ(recording->series[0].values.back(), 1499.0);
  ASSERT_EQ(recording->events.size(), 1U);
  EXPECT_EQ(recording->events[0].kind, "stop");
}

TEST(Hdf5RecorderTest, RowsReservedButNeverWrittenAreNotReadAsData) {
  // A crash between the extent's growth and the chunk's write, or a full disk, leaves rows
  // the file has room for but no data in. They must not read as samples (HDF5's default fill,
  // 0.0 at cycle 0, would look like a stage at the origin).
  const std::string path = scratch_path("reserved.h5");
  {
    auto recorder = Recorder::create(path, "lode run");
    ASSERT_TRUE(recorder) << recorder.error();
    auto series = (*recorder)->add_series({"s", "", "signal", {"v"}, {"m"}, 1000.0, 1000.0, 1});
    ASSERT_TRUE(series) << series.error();
    for (std::uint64_t cycle = 0; cycle < 100; ++cycle) {
      const double value = 1.0 + static_cast<double>(cycle);
      (*recorder)->append(*series, cycle, static_cast<std::int64_t>(cycle) * 1'000'000, 0, &value);
    }
    (*recorder)->add_event(3, 0, "note", "kept");
    ASSERT_TRUE((*recorder)->close());
  }
  // What the dying writer left: every column, and the event columns, 40 rows longer.
  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    for (const char* column : {"/signals/s/cycle", "/signals/s/stamp_ns", "/signals/s/captured_ns",
                               "/signals/s/time_s", "/signals/s/v", "/events/cycle", "/events/stamp_ns",
                               "/events/kind", "/events/text"}) {
      const hid_t dataset = H5Dopen2(file, column, H5P_DEFAULT);
      ASSERT_GE(dataset, 0) << column;
      const hsize_t grown = std::string(column).rfind("/events", 0) == 0 ? 41 : 140;
      ASSERT_GE(H5Dset_extent(dataset, &grown), 0) << column;
      H5Dclose(dataset);
    }
    H5Fclose(file);
  }
  auto recording = read_recording(path);
  ASSERT_TRUE(recording) << recording.error();
  ASSERT_EQ(recording->series.size(), 1U);
  EXPECT_EQ(recording->series[0].rows(), 100U);
  EXPECT_EQ(recording->series[0].values.back(), 100.0);
  EXPECT_EQ(recording->events.size(), 1U);
  std::string warnings;
  for (const auto& w : recording->warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("rows 100 to 139 were reserved but never written"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("/events: rows 1 to 40 were reserved but never written"), std::string::npos) << warnings;
}

// ---- Crash safety and the files the Python check reads ------------------------------------

// The content both the crash test and read_recording.py check: series "glsdc.pose" (x, y, θ
// in m, m, rad) at 1 kHz, x = cycle * 1e-3, y = -cycle, θ = NaN on every 1000th cycle else
// sin(cycle * 1e-3); series "plant.gap" (gap in m, decimation 10).
constexpr std::uint64_t kFlushedCycles = 10'000;
constexpr std::uint64_t kCyclesAfterFlush = 200'000;  // lost in the crash, or not: never required

void write_known_rows(Recorder& rec, int pose, int gap, std::uint64_t from, std::uint64_t to) {
  for (std::uint64_t cycle = from; cycle < to; ++cycle) {
    const auto stamp = static_cast<std::int64_t>(cycle) * 1'000'000;
    const double c = static_cast<double>(cycle);
    const double pose_values[3] = {c * 1e-3, -c,
                                   cycle % 1000 == 0 ? std::numeric_limits<double>::quiet_NaN() : std::sin(c * 1e-3)};
    rec.append(pose, cycle, stamp, stamp + 42, pose_values);
    if (cycle % 10 == 0) {
      const double gap_value = 1e-3 + c * 1e-9;
      rec.append(gap, cycle, stamp, stamp + 43, &gap_value);
    }
  }
}

/// Writes the known content; `crash` = _exit() after the flush without closing.
[[noreturn]] void write_known_file_and_exit(const std::string& path, bool crash) {
  auto recorder = Recorder::create(path, "lode run");
  if (!recorder) _exit(10);
  Recorder& rec = **recorder;
  rec.set_attribute("pipeline", "kawato_planar");
  rec.set_attribute("base_rate_hz", 1000.0);
  auto pose = rec.add_series(
      {"glsdc.pose", "lode/kawato_planar/glsdc/pose", "signal", {"x", "y", "θ"}, {"m", "m", "rad"}, 1000.0, 1000.0, 1});
  auto gap = rec.add_series({"plant.gap", "", "raw", {"gap"}, {"m"}, 100.0, 1000.0, 10});
  if (!pose || !gap) _exit(11);
  rec.add_event(0, 0, "start", "run started");
  write_known_rows(rec, *pose, *gap, 0, kFlushedCycles);
  rec.add_event(kFlushedCycles - 1, static_cast<std::int64_t>(kFlushedCycles - 1) * 1'000'000, "fault", "ADC timeout");
  if (!rec.flush()) _exit(12);
  if (crash) {
    write_known_rows(rec, *pose, *gap, kFlushedCycles, kFlushedCycles + kCyclesAfterFlush);
    _exit(0);  // no close(), no destructor, no atexit: what a crash leaves behind
  }
  if (!rec.close()) _exit(13);
  _exit(0);
}

/// Runs the writer in a child process so a crash really is a process dying.
void write_known_file_in_child(const std::string& path, bool crash) {
  std::fflush(nullptr);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) write_known_file_and_exit(path, crash);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << "the writer failed (exit code 1x = step x of write_known_file_and_exit)";
}

void expect_known_content(const std::string& path) {
  auto recording = read_recording(path);
  ASSERT_TRUE(recording) << recording.error();
  ASSERT_EQ(recording->series.size(), 2U);
  const SeriesData& pose = recording->series[0];
  EXPECT_EQ(pose.info.names, (std::vector<std::string>{"x", "y", "θ"}));
  ASSERT_GE(pose.rows(), kFlushedCycles) << "a flushed sample was lost";
  std::size_t mismatches = 0;
  for (std::uint64_t cycle = 0; cycle < kFlushedCycles; ++cycle) {
    const double c = static_cast<double>(cycle);
    mismatches += pose.cycle[cycle] != cycle;
    mismatches += pose.captured_ns[cycle] != static_cast<std::int64_t>(cycle) * 1'000'000 + 42;
    mismatches += pose.values[cycle * 3] != c * 1e-3;
    mismatches += pose.values[cycle * 3 + 1] != -c;
    mismatches +=
        cycle % 1000 == 0 ? !std::isnan(pose.values[cycle * 3 + 2]) : pose.values[cycle * 3 + 2] != std::sin(c * 1e-3);
  }
  EXPECT_EQ(mismatches, 0U);
  EXPECT_GE(recording->series[1].rows(), kFlushedCycles / 10);
  ASSERT_GE(recording->events.size(), 2U);
  EXPECT_EQ(recording->events[1].text, "ADC timeout");
}

TEST(Hdf5RecorderTest, FlushedSamplesSurviveACrash) {
  const std::string path = scratch_path("crashed.h5");
  write_known_file_in_child(path, /*crash=*/true);
  expect_known_content(path);
}

/// A copy of `from` at `to` with `mangle` applied to its bytes.
template <typename Mangle>
void copy_damaged(const std::string& from, const std::string& to, Mangle&& mangle) {
  std::string bytes(static_cast<std::size_t>(fs::file_size(from)), '\0');
  std::ifstream(from, std::ios::binary).read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  mangle(bytes);
  std::ofstream(to, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// The global heap holds a file's variable-length strings (attributes, event texts) in
// collections: "GCOL", version, 3 reserved, the collection's size (8); then objects: index (2),
// references (2), reserved (4), size (8), the bytes. Offset of the size of the object whose
// bytes are `text` (found by its stated size followed by the text), or npos.
std::size_t heap_object_size_at(const std::string& bytes, const std::string& text) {
  std::string header(8, '\0');
  const std::uint64_t size = text.size();
  std::memcpy(header.data(), &size, sizeof size);
  const std::size_t at = bytes.find(header + text, bytes.find("GCOL"));
  return at;
}

// HDF5 1.10 copies a heap object with the size the heap states: a size of 1 MiB in a 4 KiB
// collection made this very process die with SIGSEGV before each file was read in a child
// first. Once in a root attribute (the first object), once in a series' unit.
TEST(Hdf5RecorderTest, AHeapThatCrashesHdf5IsAnErrorNotACrash) {
  const std::string good = scratch_path("heap_good.h5");
  write_known_file_in_child(good, /*crash=*/false);
  const std::uint64_t oversized = 1 << 20;
  const std::string root = scratch_path("heap_root_oversized.h5");
  copy_damaged(good, root, [&](std::string& bytes) {
    const std::size_t collection = bytes.find("GCOL");
    ASSERT_NE(collection, std::string::npos) << good << " has no global heap";
    std::memcpy(bytes.data() + collection + 16 + 8, &oversized, sizeof oversized);
  });
  const std::string series = scratch_path("heap_series_oversized.h5");
  copy_damaged(good, series, [&](std::string& bytes) {
    // glsdc.pose's third unit: read only by read_series (a series' names are read by more)
    const std::size_t size_at = heap_object_size_at(bytes, "rad");
    ASSERT_NE(size_at, std::string::npos) << "no heap object holds the unit rad";
    std::memcpy(bytes.data() + size_at, &oversized, sizeof oversized);
  });
  for (const std::string& bad : {root, root, series}) {  // the second from the process's verdict
    auto recording = read_recording(bad);
    ASSERT_FALSE(recording);
    EXPECT_NE(recording.error().find(bad), std::string::npos) << recording.error();
    EXPECT_NE(recording.error().find("damaged"), std::string::npos) << recording.error();
    EXPECT_NE(recording.error().find("SIGSEGV"), std::string::npos) << recording.error();
  }
  auto reader = SeriesReader::open(series);
  ASSERT_FALSE(reader);
  EXPECT_NE(reader.error().find("SIGSEGV"), std::string::npos) << reader.error();
  EXPECT_FALSE(read_cost(series, SeriesSelection::all()));
  expect_known_content(good);  // the undamaged original reads as before
}

// A variable-length string is stored as its length, its heap collection's address and its
// index in it. A damaged length made HDF5 allocate and clear that many bytes (5 GB, 35 s,
// seen in fuzzing) before it read garbage; the child's memory allowance makes the allocation
// fail at once, and the file is refused with that, without being read here at all.
TEST(Hdf5RecorderTest, AStringLengthOfAGigabyteIsRefusedQuickly) {
  const std::string good = scratch_path("heap_good_3.h5");
  const std::string bad = scratch_path("string_length.h5");
  write_known_file_in_child(good, /*crash=*/false);
  copy_damaged(good, bad, [&](std::string& bytes) {
    const std::string text = "lodestone-recording";  // the root attribute `format`
    const std::size_t size_at = heap_object_size_at(bytes, text);
    ASSERT_NE(size_at, std::string::npos);
    std::uint16_t index = 0;
    std::memcpy(&index, bytes.data() + size_at - 8, sizeof index);
    const std::uint64_t collection = bytes.rfind("GCOL", size_at);
    std::string reference(16, '\0');  // length (4), collection address (8), index (4)
    const std::uint32_t length = static_cast<std::uint32_t>(text.size()), index32 = index;
    std::memcpy(reference.data(), &length, 4);
    std::memcpy(reference.data() + 4, &collection, 8);
    std::memcpy(reference.data() + 12, &index32, 4);
    const std::size_t at = bytes.find(reference);
    ASSERT_NE(at, std::string::npos) << "no reference to the format string";
    const std::uint32_t gigabyte = 1u << 30;
    std::memcpy(bytes.data() + at, &gigabyte, 4);
  });
  auto recording = read_recording(bad);
  ASSERT_FALSE(recording);
  EXPECT_NE(recording.error().find("attribute 'format'"), std::string::npos) << recording.error();
  EXPECT_NE(recording.error().find("memory allocation failed"), std::string::npos) << recording.error();
}

// A zeroed object header sends HDF5 1.10 round a loop it never leaves: the reader stops the
// child after 20 s without progress and says so, instead of hanging with it.
TEST(Hdf5RecorderTest, AHeapThatHangsHdf5IsStopped) {
  const std::string good = scratch_path("heap_good_2.h5");
  const std::string bad = scratch_path("heap_looping.h5");
  write_known_file_in_child(good, /*crash=*/false);
  copy_damaged(good, bad, [&](std::string& bytes) {
    const std::size_t collection = bytes.find("GCOL");
    ASSERT_NE(collection, std::string::npos) << good << " has no global heap";
    std::memset(bytes.data() + collection + 16, 0, 16);
  });
  const auto start = std::chrono::steady_clock::now();
  auto recording = read_recording(bad);
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_FALSE(recording);
  EXPECT_NE(recording.error().find("no progress"), std::string::npos) << recording.error();
  EXPECT_LT(waited_s, 120.0);
}

// Also run by ctest as hdf5_recorder_write_fixture, with LODE_RECORD_FIXTURE_OUT set to the
// build folder, for hdf5_recorder_python (read_recording.py) and hdf5_recorder_h5dump. Run
// as a plain test it writes to a private scratch folder, so that the two runs never write
// the same file while Python reads it (ctest -j).
TEST(Hdf5RecorderTest, WritesFilesForPython) {
  const char* fixture_dir = std::getenv("LODE_RECORD_FIXTURE_OUT");
  const std::string closed_path =
      fixture_dir != nullptr ? std::string(fixture_dir) + "/python_check.h5" : scratch_path("python_check.h5");
  const std::string crashed_path = fixture_dir != nullptr ? std::string(fixture_dir) + "/python_check_crashed.h5"
                                                          : scratch_path("python_check_crashed.h5");
  write_known_file_in_child(closed_path, /*crash=*/false);
  write_known_file_in_child(crashed_path, /*crash=*/true);
  expect_known_content(closed_path);
  expect_known_content(crashed_path);
  auto closed = read_recording(closed_path);
  ASSERT_TRUE(closed);
  EXPECT_EQ(closed->series[0].rows(), kFlushedCycles);  // closed: exactly what was appended
}

// ---- Errors --------------------------------------------------------------------------------

TEST(Hdf5RecorderTest, ErrorsNameThePathAndTheField) {
  auto missing_dir = Recorder::create("/nonexistent-dir/x.h5", "lode record");
  ASSERT_FALSE(missing_dir);
  EXPECT_NE(missing_dir.error().find("/nonexistent-dir/x.h5"), std::string::npos) << missing_dir.error();
  EXPECT_NE(missing_dir.error().find("the folder /nonexistent-dir does not exist"), std::string::npos)
      << missing_dir.error();
  // A folder where the file should go is named as such, not in HDF5's words.
  auto folder = Recorder::create(::testing::TempDir(), "lode record");
  ASSERT_FALSE(folder);
  EXPECT_NE(folder.error().find("cannot create the file: it is a folder"), std::string::npos) << folder.error();

  const std::string path = scratch_path("errors.h5");
  auto recorder = Recorder::create(path, "lode record");
  ASSERT_TRUE(recorder) << recorder.error();
  Recorder& rec = **recorder;
  const auto error_of = [&](const SeriesInfo& info) {
    auto handle = rec.add_series(info);
    return handle ? std::string("accepted") : handle.error();
  };
  EXPECT_NE(error_of({"a/b", "", "signal", {"x"}, {"m"}}).find("without '/'"), std::string::npos);
  EXPECT_NE(error_of({"", "", "signal", {"x"}, {"m"}}).find("non-empty"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "video", {"x"}, {"m"}}).find("kind 'video'"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {"x", "y"}, {"m"}}).find("units has 1"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {}, {}}).find("names is empty"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {"x", "x"}, {"m", "m"}}).find("'x' appears twice"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {"time_s", "value_time_s"}, {"s", "s"}}).find("another element"),
            std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {"x"}, {"m"}, 1000, 1000, 0}).find("decimation"), std::string::npos);
  EXPECT_NE(error_of({"s", "", "signal", {"x"}, {"m"}, -1}).find("rate_hz"), std::string::npos);
  EXPECT_EQ(error_of({"s", "", "signal", {"x"}, {"m"}}), "accepted");
  EXPECT_NE(error_of({"s", "", "signal", {"x"}, {"m"}}).find("already exists"), std::string::npos);

  const double value = 0;
  rec.append(7, 0, 0, 0, &value);  // unknown series: reported by the next flush
  const Status flushed = rec.flush();
  EXPECT_FALSE(flushed);
  EXPECT_NE(flushed.message().find("unknown series 7"), std::string::npos) << flushed.message();
  EXPECT_TRUE(rec.flush()) << "an error is reported once";
  EXPECT_TRUE(rec.close());
  EXPECT_FALSE(rec.flush());

  auto not_hdf5 = read_recording("/proc/self/status");
  ASSERT_FALSE(not_hdf5);
  EXPECT_NE(not_hdf5.error().find("/proc/self/status"), std::string::npos) << not_hdf5.error();
}

// ---- Speed (printed, asserted only loosely: two shared, noisy cores) ------------------------

TEST(Hdf5RecorderTest, WriteSpeedOfAThreeValueSeries) {
  const std::string path = scratch_path("speed.h5");
  constexpr std::uint64_t kSamples = 2'000'000;
  const auto start = std::chrono::steady_clock::now();
  {
    auto recorder = Recorder::create(path, "lode record");
    ASSERT_TRUE(recorder) << recorder.error();
    auto series = (*recorder)->add_series(
        {"glsdc.pose", "", "signal", {"x", "y", "theta"}, {"m", "m", "rad"}, 10'000.0, 10'000.0, 1});
    ASSERT_TRUE(series) << series.error();
    for (std::uint64_t cycle = 0; cycle < kSamples; ++cycle) {
      const double c = static_cast<double>(cycle);
      const double values[3] = {c, -c, c * 0.5};
      const auto stamp = static_cast<std::int64_t>(cycle) * 100'000;
      (*recorder)->append(*series, cycle, stamp, stamp + 7, values);
      if (cycle % 10'000 == 9'999) {  // once a second of data
        ASSERT_TRUE((*recorder)->flush());
      }
    }
    ASSERT_TRUE((*recorder)->close());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double rate = static_cast<double>(kSamples) / seconds;
  std::printf("[ speed    ] %llu samples of 3 values in %.3f s: %.3g samples/s, file %.1f MB (%.1f bytes/sample)\n",
              static_cast<unsigned long long>(kSamples), seconds, rate, static_cast<double>(fs::file_size(path)) / 1e6,
              static_cast<double>(fs::file_size(path)) / static_cast<double>(kSamples));
  EXPECT_GT(rate, 20'000.0) << "far below a 10 kHz pipeline with margin";
}

}  // namespace
}  // namespace lode::record
