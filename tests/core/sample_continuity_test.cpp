// What `lode record` and `lode echo` say is missing: lost samples are steps in a writer's
// sequence numbers; a step in the cycle alone is a sample never sent, which is a period the
// loop skipped only where the pipeline's timing reports show no telemetry drop around it.
#include <gtest/gtest.h>

#include "sample_continuity.hpp"

namespace {

using lode::cli::SampleContinuity;

constexpr std::uint64_t kWriter = 0x1234;

TEST(SampleContinuity, ConsecutiveSamplesMissNothing) {
  SampleContinuity c(1);
  for (std::uint64_t k = 0; k < 10; ++k) c.add(kWriter, k + 1, 100 + k);
  EXPECT_EQ(c.received(), 10u);
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.unsent(), 0u);
  EXPECT_EQ(c.classify().missing, 0u);
  EXPECT_EQ(c.last_cycle(), 109u);
}

TEST(SampleContinuity, AStepInTheSequenceIsLostWhateverTheCycles) {
  SampleContinuity c(1);
  c.add(kWriter, 1, 10);
  c.add(kWriter, 4, 13);  // samples 2 and 3 (cycles 11, 12) never arrived
  EXPECT_EQ(c.lost(), 2u);
  EXPECT_EQ(c.unsent(), 0u);
  c.timing(20, 0);
  EXPECT_EQ(c.classify().missing, 2u);
  EXPECT_EQ(c.classify().skipped, 0u);
}

TEST(SampleContinuity, ACycleStepWithoutASequenceStepIsSkippedWhenTheTimingShowsNoDrop) {
  SampleContinuity c(1);
  c.add(kWriter, 1, 10);
  c.add(kWriter, 2, 14);  // cycles 11-13 published nothing
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.unsent(), 3u);
  EXPECT_FALSE(c.timing_reaches(14));
  // Without a timing report after the gap it cannot be placed: missing, never "complete".
  EXPECT_EQ(c.classify().missing, 3u);
  c.timing(16, 0);
  EXPECT_TRUE(c.timing_reaches(14));
  EXPECT_EQ(c.classify().missing, 0u);
  EXPECT_EQ(c.classify().skipped, 3u);
}

TEST(SampleContinuity, ATelemetryDropAroundTheGapMakesItMissing) {
  SampleContinuity c(1);
  c.timing(5, 0);
  c.add(kWriter, 1, 10);
  c.add(kWriter, 2, 14);  // cycles 11-13 not sent: skipped, or dropped by the pipeline's full rings?
  c.add(kWriter, 3, 15);
  c.add(kWriter, 4, 21);  // 16-20 not sent
  c.add(kWriter, 5, 30);  // 22-29 not sent
  c.timing(20, 3);        // the rings dropped 3 somewhere between cycles 5 and 20
  c.timing(40, 3);        // and nothing after that
  const auto v = c.classify();
  EXPECT_EQ(v.missing, 3u + 5u);  // the gaps that overlap cycles 5-20: either may hold the drops
  EXPECT_EQ(v.skipped, 8u);       // 22-29: between two reports of 3
}

TEST(SampleContinuity, ADropBeforeTheFirstReportCounts) {
  // Joined mid-run: the first report already shows drops, so a gap before it is not placed.
  SampleContinuity c(1);
  c.add(kWriter, 1, 10);
  c.add(kWriter, 2, 12);
  c.timing(20, 5);
  EXPECT_EQ(c.classify().missing, 1u);
  // Nothing dropped since the run began: the same gap was a skipped period.
  SampleContinuity d(1);
  d.add(kWriter, 1, 10);
  d.add(kWriter, 2, 12);
  d.timing(20, 0);
  EXPECT_EQ(d.classify().skipped, 1u);
}

TEST(SampleContinuity, EqualReportsInARowAreKeptAsTheirEnds) {
  // Many reports with the same count, then a rise: a gap inside the equal run is placed by it.
  SampleContinuity c(1);
  for (std::uint64_t k = 1; k <= 100; ++k) c.timing(k * 10, 0);
  c.timing(1010, 2);
  c.add(kWriter, 1, 500);
  c.add(kWriter, 2, 503);  // between the reports at 500 and 510, both 0
  c.add(kWriter, 3, 1005);  // a gap across the rise to 2
  const auto v = c.classify();
  EXPECT_EQ(v.skipped, 2u);
  EXPECT_EQ(v.missing, 501u);
}

TEST(SampleContinuity, DecimatedTopicsCountSamplesNotCycles) {
  SampleContinuity c(4);
  c.add(kWriter, 1, 0);
  c.add(kWriter, 2, 4);
  c.add(kWriter, 3, 16);  // samples of cycles 8 and 12 not sent
  c.add(kWriter, 5, 24);  // the sample of cycle 20 sent and lost
  EXPECT_EQ(c.lost(), 1u);
  EXPECT_EQ(c.unsent(), 2u);
  c.timing(30, 0);
  EXPECT_EQ(c.classify().skipped, 2u);
  EXPECT_EQ(c.classify().missing, 1u);
}

TEST(SampleContinuity, UnknownSequenceNumbersCountEveryCycleStepAsLost) {
  SampleContinuity c(1);
  c.add(0, 0, 10);
  c.add(0, 0, 14);
  c.timing(20, 0);
  EXPECT_EQ(c.lost(), 3u);
  EXPECT_EQ(c.classify().missing, 3u);
}

TEST(SampleContinuity, EachWriterIsFollowedOnItsOwn) {
  // Two namesake pipelines on one topic, on other cycle counts, interleaved: nothing missing.
  SampleContinuity c(1);
  for (std::uint64_t k = 0; k < 5; ++k) {
    c.add(1, k + 1, 1000 + k);
    c.add(2, k + 1, 7 + k);
  }
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.unsent(), 0u);
  EXPECT_EQ(c.out_of_order(), 0u);
  EXPECT_EQ(c.writers(), 2u);
  // A repeated sample of one of them is out of order, not a gap.
  c.add(1, 3, 1002);
  EXPECT_EQ(c.out_of_order(), 1u);
  EXPECT_EQ(c.lost(), 0u);
}

TEST(SampleContinuity, ANewRunForgetsTheOldRunsReports) {
  SampleContinuity c(1);
  c.add(kWriter, 1, 10);
  c.add(kWriter, 2, 12);
  c.timing(100, 0);  // placed: skipped
  EXPECT_EQ(c.classify().skipped, 1u);
  c.timing(5, 0);  // the pipeline restarted: the old gap can no longer be placed
  EXPECT_EQ(c.classify().skipped, 0u);
  EXPECT_EQ(c.classify().missing, 1u);
}

TEST(SampleContinuity, GapsBeyondTheLimitCountAsMissing) {
  SampleContinuity c(1);
  std::uint64_t cycle = 0, sequence = 1;
  c.add(kWriter, sequence++, cycle);
  for (std::size_t k = 0; k < SampleContinuity::kMaxUnsentGaps + 10; ++k) {
    cycle += 2;  // one cycle not sent each time
    c.add(kWriter, sequence++, cycle);
  }
  c.timing(cycle + 1, 0);
  const auto v = c.classify();
  EXPECT_EQ(v.skipped, SampleContinuity::kMaxUnsentGaps);
  EXPECT_EQ(v.missing, 10u);
}

}  // namespace
