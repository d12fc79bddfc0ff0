// `lode plot`'s arithmetic on synthetic signals whose answers are known: the display
// decimation keeps every minimum and maximum, the step metrics of a response with a known
// rise and overshoot, Welch's PSD of white noise and of a sine, the base64 of the page's
// arrays, and the exact recovery of a timing histogram's bins.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>

#include "analysis.hpp"
#include "plot_data.hpp"
#include "plot_html.hpp"
#include "plot_metrics.hpp"
#include "run_timing.hpp"

namespace lode::plot {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<double> noisy_signal_with_spikes(std::size_t n) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> v(n);
  for (std::size_t k = 0; k < n; ++k) v[k] = std::sin(1e-3 * static_cast<double>(k)) + 0.1 * noise(rng);
  // Single-sample spikes, the excursions a decimation that averages or picks samples loses.
  v[12345] = 50.0;
  v[777777] = -40.0;
  v[n - 1] = 30.0;  // in the short last bucket
  return v;
}

TEST(MinMaxPyramid, EveryBucketHoldsItsSamplesExtremes) {
  const auto values = noisy_signal_with_spikes(1'000'003);
  const auto levels = min_max_pyramid(values, 16, 4, 2048);
  ASSERT_GE(levels.size(), 4u);
  for (const auto& level : levels) {
    ASSERT_EQ(level.min.size(), (values.size() + level.bucket - 1) / level.bucket) << level.bucket;
    for (std::size_t b = 0; b < level.min.size(); ++b) {
      const auto first = values.begin() + static_cast<std::ptrdiff_t>(b * level.bucket);
      const auto last = values.begin() + static_cast<std::ptrdiff_t>(std::min(values.size(), (b + 1) * level.bucket));
      ASSERT_EQ(level.min[b], *std::min_element(first, last)) << "bucket " << b << " of " << level.bucket;
      ASSERT_EQ(level.max[b], *std::max_element(first, last)) << "bucket " << b << " of " << level.bucket;
    }
    // The spikes survive at every level, however coarse.
    EXPECT_EQ(*std::max_element(level.max.begin(), level.max.end()), 50.0);
    EXPECT_EQ(*std::min_element(level.min.begin(), level.min.end()), -40.0);
    EXPECT_EQ(level.max.back(), 30.0);
  }
  EXPECT_EQ(levels[1].bucket, 64u);
  EXPECT_LE(levels.back().min.size(), 2048u);
  EXPECT_GT(levels[levels.size() - 2].min.size(), 2048u);
}

TEST(MinMaxPyramid, NaNIsSkippedAndABucketOfNaNStaysNaN) {
  std::vector<double> values(64, kNaN);
  values[3] = 2.0;
  values[5] = -1.0;
  const auto levels = min_max_pyramid(values, 16, 4, 1);
  ASSERT_EQ(levels.size(), 2u);
  EXPECT_EQ(levels[0].min[0], -1.0);
  EXPECT_EQ(levels[0].max[0], 2.0);
  EXPECT_TRUE(std::isnan(levels[0].min[1]) && std::isnan(levels[0].max[3]));
  EXPECT_EQ(levels[1].min[0], -1.0);
  EXPECT_EQ(levels[1].max[0], 2.0);
}

TEST(MinMaxPyramid, ShortSignalsNeedNoLevel) {
  EXPECT_TRUE(min_max_pyramid(std::vector<double>(16, 1.0)).empty());
}

// A response to a unit step at t = 1 s (1 ms samples) that rises linearly to 1.2 in 100 ms,
// falls linearly back to 1 in the next 100 ms and stays: 10 % at 1 + 0.1 / 12 s, 90 % at
// 1 + 0.9 / 12 s (rise 66.7 ms), overshoot 20 %, inside a 2 % band from 1.19 s on,
// steady-state error 0.
TEST(StepMetrics, KnownRiseOvershootSettlingOfAPiecewiseLinearResponse) {
  std::vector<double> t;
  analysis::Series reference{{{"x", "m"}}, {}}, response{{{"x", "m"}}, {}};
  for (int k = 0; k <= 3000; ++k) {
    const double time = k * 1e-3;
    t.push_back(time);
    reference.values.push_back(k >= 1000 ? 1.0 : 0.0);
    double y = 0.0;
    if (time >= 1.2) y = 1.0;
    else if (time >= 1.1) y = 1.2 - 2.0 * (time - 1.1);
    else if (time >= 1.0) y = 12.0 * (time - 1.0);
    response.values.push_back(y);
  }
  const auto steps = analysis::step_responses(t, reference, response, 0.025);
  ASSERT_EQ(steps.size(), 1u);
  const auto& s = steps.front();
  EXPECT_NEAR(s.time_s, 1.0, 1e-12);
  EXPECT_NEAR(s.amplitude, 1.0, 1e-12);
  EXPECT_NEAR(s.rise_start_s, 1.0 + 0.1 / 12.0, 1e-9);
  EXPECT_NEAR(s.rise_time_s, 0.8 / 12.0, 1e-9);
  EXPECT_NEAR(s.overshoot_pct, 20.0, 1e-6);
  // Last sample outside +-0.025 is 1.187 s (y = 1.026): settled from the next, 1.188 s.
  EXPECT_NEAR(s.settling_time_s, 0.188, 1e-9);
  EXPECT_NEAR(s.settling_band, 0.025, 1e-12);
  EXPECT_NEAR(s.steady_state_error, 0.0, 1e-12);
}

TEST(WelchPsd, WhiteNoiseIsFlatAtTwiceTheVarianceOverTheRate) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 2.0);
  std::vector<double> v(1 << 16);
  for (auto& x : v) x = 5.0 + noise(rng);  // the mean is removed per segment
  const double fs = 800.0;
  const std::size_t segment = welch_segment(v.size());
  EXPECT_EQ(segment, 8192u);
  const auto s = welch_psd(v, fs, segment);
  ASSERT_EQ(s.frequency_hz.size(), segment / 2 + 1);
  EXPECT_EQ(s.segments, 2 * v.size() / segment - 1);
  EXPECT_DOUBLE_EQ(s.frequency_hz.back(), fs / 2);
  double mean_density = 0.0, variance = 0.0;
  for (std::size_t b = 1; b + 1 < s.density.size(); ++b) mean_density += s.density[b];
  mean_density /= static_cast<double>(s.density.size() - 2);
  for (std::size_t b = 0; b + 1 < s.density.size(); ++b) variance += s.density[b] * fs / static_cast<double>(segment);
  EXPECT_NEAR(mean_density, 2.0 * 4.0 / fs, 0.05 * 2.0 * 4.0 / fs);
  EXPECT_NEAR(variance, 4.0, 0.1);  // Parseval: the density integrates to the variance
}

TEST(WelchPsd, ASinePeaksAtItsFrequency) {
  const double fs = 1000.0, f = 125.0;
  std::vector<double> v(4096);
  for (std::size_t k = 0; k < v.size(); ++k) v[k] = std::sin(2 * M_PI * f * static_cast<double>(k) / fs);
  const auto s = welch_psd(v, fs, 512);
  const auto peak = std::max_element(s.density.begin(), s.density.end()) - s.density.begin();
  EXPECT_DOUBLE_EQ(s.frequency_hz[static_cast<std::size_t>(peak)], f);
  EXPECT_EQ(welch_segment(100), 0u);
}

TEST(WelchPsd, SegmentsSpanningNaNAreLeftOut) {
  std::vector<double> v(2048, 1.0);
  v[100] = kNaN;
  const auto s = welch_psd(v, 100.0, 256);
  EXPECT_EQ(s.segments, 15u - 1u);  // the one segment holding sample 100 (0..255)
}

TEST(Base64, MatchesRfc4648) {
  EXPECT_EQ(base64("", 0), "");
  EXPECT_EQ(base64("f", 1), "Zg==");
  EXPECT_EQ(base64("fo", 2), "Zm8=");
  EXPECT_EQ(base64("foo", 3), "Zm9v");
  EXPECT_EQ(base64("foobar", 6), "Zm9vYmFy");
}

TEST(BlobStore, ChunksOfFloat32AroundAnOffset) {
  BlobStore blobs;
  std::vector<double> values(kBlobSamples + 5, 1.0);
  const auto j = blobs.add_float32(values, 1.0);
  EXPECT_EQ(j["length"], values.size());
  EXPECT_EQ(j["blobs"].size(), 2u);
  EXPECT_EQ(j["offset"], 1.0);
  // 12288 zeros as Float32 are 65536 base64 characters: one text node in Chromium.
  EXPECT_EQ(blobs.bytes(), 65536u + base64(std::vector<float>(5).data(), 20).size());
}

TEST(HistogramBins, EveryBinsCountIsRecoveredExactly) {
  Histogram h;
  std::mt19937 rng(3);
  std::lognormal_distribution<double> latency(8.0, 1.0);
  std::map<int, std::uint64_t> expected;
  for (int k = 0; k < 20000; ++k) {
    const auto ns = static_cast<std::int64_t>(latency(rng));
    h.record(ns);
    ++expected[Histogram::bin_of(ns)];
  }
  const auto bins = cli::histogram_bins(h);
  ASSERT_EQ(bins.size(), expected.size());
  std::size_t i = 0;
  for (const auto& [bin, count] : expected) {
    EXPECT_EQ(bins[i].second, count) << "bin " << bin;
    EXPECT_EQ(bins[i].first, std::min(Histogram::upper_edge(bin), h.max())) << "bin " << bin;
    ++i;
  }
  Histogram empty;
  EXPECT_TRUE(cli::histogram_bins(empty).empty());
  Histogram one;
  one.record(42);
  EXPECT_EQ(cli::histogram_bins(one), (std::vector<std::pair<std::int64_t, std::uint64_t>>{{42, 1}}));
}

}  // namespace
}  // namespace lode::plot
