// `lode replay`'s bit-for-bit check (compare_recording_files): two recordings are the same
// only when every value has the same bits. Equal as doubles is not enough (-0.0 == +0.0, and
// an estimator that flips the sign of a zero has changed), nor is "both NaN" (a NaN's payload
// is part of what was recorded); the same NaN bits on both sides are the same value.
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lode/record/hdf5_recorder.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"
#include "replay.hpp"

namespace lode::cli {
namespace {

constexpr std::size_t kRows = 40;
constexpr std::size_t kWidth = 3;

/// Row k of series "kf.pose": three ordinary values.
std::vector<double> pose_values() {
  std::vector<double> v(kRows * kWidth);
  for (std::size_t k = 0; k < kRows; ++k)
    for (std::size_t i = 0; i < kWidth; ++i) v[k * kWidth + i] = 1e-3 * static_cast<double>(k) - 0.5 * static_cast<double>(i);
  return v;
}

/// A recording of "kf.pose" (the given values) and, with `extra`, of one more series.
std::string write_recording(const std::string& name, const std::vector<double>& pose, bool extra = false) {
  const std::string path = lode::testing::scratch_path(name);
  auto recorder = record::Recorder::create(path, "lode run");
  EXPECT_TRUE(recorder) << recorder.error();
  if (!recorder) return path;
  std::vector<std::uint64_t> cycles(kRows);
  std::vector<std::int64_t> stamps(kRows);
  for (std::size_t k = 0; k < kRows; ++k) {
    cycles[k] = k;
    stamps[k] = static_cast<std::int64_t>(k) * 1'250'000;
  }
  const auto add = [&](const std::string& series, const std::vector<double>& values) {
    const record::SeriesInfo info{series, "", "signal", {"x", "y", "theta_z"}, {"m", "m", "rad"}, 800.0, 800.0, 1};
    auto handle = (*recorder)->add_series(info);
    ASSERT_TRUE(handle) << handle.error();
    (*recorder)->append_rows(*handle, kRows, cycles.data(), stamps.data(), values.data(), kWidth);
  };
  add("kf.pose", pose);
  if (extra) add("kf.velocity", pose_values());
  EXPECT_TRUE((*recorder)->close()) << path;
  return path;
}

double with_bits(std::uint64_t bits) { return std::bit_cast<double>(bits); }

TEST(ReplayCompare, IdenticalRecordingsAreBitIdentical) {
  const auto a = write_recording("same_a.h5", pose_values());
  const auto b = write_recording("same_b.h5", pose_values());
  const auto r = compare_recording_files(a, b);
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->series, 1U);
  EXPECT_EQ(r->cycles, kRows);
  EXPECT_EQ(r->first_difference, "");
  EXPECT_TRUE(r->only_in_one.empty());
}

TEST(ReplayCompare, TheSameNanBitsAreTheSameValue) {
  auto values = pose_values();
  values[7 * kWidth + 1] = with_bits(0x7ff8000000000123ULL);
  const auto r = compare_recording_files(write_recording("nan_a.h5", values), write_recording("nan_b.h5", values));
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->first_difference, "") << "a NaN recorded and replayed with the same bits differs from itself";
}

TEST(ReplayCompare, ASignedZeroDiffers) {
  auto recorded = pose_values(), replayed = pose_values();
  recorded[12 * kWidth + 2] = 0.0;
  replayed[12 * kWidth + 2] = -0.0;
  const auto r =
      compare_recording_files(write_recording("zero_a.h5", recorded), write_recording("zero_b.h5", replayed));
  ASSERT_TRUE(r) << r.error();
  EXPECT_NE(r->first_difference.find("series kf.pose, cycle 12, element theta_z"), std::string::npos)
      << "+0.0 recorded, -0.0 replayed: " << r->first_difference;
}

TEST(ReplayCompare, ANanPayloadDiffers) {
  auto recorded = pose_values(), replayed = pose_values();
  recorded[30 * kWidth + 1] = with_bits(0x7ff8000000000001ULL);
  replayed[30 * kWidth + 1] = with_bits(0x7ff8000000000002ULL);
  const auto r = compare_recording_files(write_recording("payload_a.h5", recorded),
                                         write_recording("payload_b.h5", replayed));
  ASSERT_TRUE(r) << r.error();
  EXPECT_NE(r->first_difference.find("series kf.pose, cycle 30, element y"), std::string::npos)
      << "two NaNs with different payloads: " << r->first_difference;
  ASSERT_EQ(r->largest_differences.size(), 1U);
  EXPECT_NE(r->largest_differences[0].find("largest relative difference inf in kf.pose.y at cycle 30"),
            std::string::npos)
      << r->largest_differences[0];
}

TEST(ReplayCompare, TheFirstDifferenceIsNamedWhereverItIs) {
  // Later rows differ more: the first one, in the last element of its row, is named; the
  // largest is reported beside it, relative to the element's largest recorded magnitude.
  auto recorded = pose_values(), replayed = pose_values();
  replayed[20 * kWidth + 2] += 1e-15;
  replayed[35 * kWidth + 0] += 1e-6;
  const auto r =
      compare_recording_files(write_recording("late_a.h5", recorded), write_recording("late_b.h5", replayed));
  ASSERT_TRUE(r) << r.error();
  EXPECT_NE(r->first_difference.find("series kf.pose, cycle 20, element theta_z"), std::string::npos)
      << r->first_difference;
  ASSERT_EQ(r->largest_differences.size(), 1U);
  EXPECT_NE(r->largest_differences[0].find("in kf.pose.x at cycle 35"), std::string::npos)
      << r->largest_differences[0];
}

TEST(ReplayCompare, ASeriesInOneFileOnlyIsNamed) {
  const auto r = compare_recording_files(write_recording("extra_a.h5", pose_values(), /*extra=*/true),
                                         write_recording("extra_b.h5", pose_values()));
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r->series, 1U);
  EXPECT_EQ(r->first_difference, "");
  ASSERT_EQ(r->only_in_one.size(), 1U);
  EXPECT_EQ(r->only_in_one[0], "kf.velocity (only in the recording)");
}

TEST(ReplayCompare, AMissingFileIsAnError) {
  const auto a = write_recording("present.h5", pose_values());
  EXPECT_FALSE(compare_recording_files(a, lode::testing::scratch_path("absent.h5")));
  EXPECT_FALSE(compare_recording_files(lode::testing::scratch_path("absent.h5"), a));
}

}  // namespace
}  // namespace lode::cli
