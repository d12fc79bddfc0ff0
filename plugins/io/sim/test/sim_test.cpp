// io.sim through the BlockHarness (the scheduler's port API), with plant.planar_stage as the
// plant and sensor.halbach_hall (two sensors, four channels, thesis geometry) as the
// measurement model. Checks the acquisition chain statistically (noise, quantization, mains,
// offsets), the read/write timing (a command moves the next sample by exactly a dt^2/2),
// determinism, faults, configuration errors and that a cycle does not allocate.
#include "sim.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <new>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "lode/sdk/testing/harness.hpp"


namespace {

using lode::StepStatus;
using lode::testing::BlockHarness;

constexpr double kRateHz = 800.0;
constexpr double kDt = 1.0 / kRateHz;
constexpr double kMassKg = 6.20;

const lode::Elements kCommand = {{"fx", "N"}, {"fy", "N"}, {"tz", "N*m"}};

// Sensors A and B of the thesis (positions assumed: Fig. 28 only), 2 mm gap; four channels A_a, A_b, B_a, B_b.
const std::string kHallSpec =
    "{plugin: sensor.halbach_hall, sensors: [{name: A, x_m: 0.00635, y_m: 0.09525}, "
    "{name: B, x_m: -0.00635, y_m: -0.09525}]}";
const std::string kModels = "stage: {plugin: plant.planar_stage}\nhall: " + kHallSpec + "\n";


#define REQUIRE_HALBACH() LODE_REQUIRE_PLUGINS("sensor.halbach_hall")  // io.sim needs a measurement model

/// A configured and activated board.
struct Board {
  explicit Board(const std::string& params, const std::string& models = kModels)
      : h("io.sim", "plant: stage\nsensors: hall\n" + params, kRateHz, models) {
    h.feed("command", kCommand);
    const lode::Status configured = h.configure();
    ok = configured.is_ok();
    if (!ok) {
      why = h.diagnostics();
      return;
    }
    ok = h.activate().is_ok();
  }
  BlockHarness h;
  bool ok = false;
  std::string why;
};

std::vector<double> copy(std::span<const double> s) { return {s.begin(), s.end()}; }

double json_number(const lode::Json& j, const std::string& key) {
  const lode::Json* v = j.find(key);
  return v ? v->as_number() : std::nan("");
}

TEST(IoSim, PortsFollowPlantAndSensors) {
  REQUIRE_HALBACH();
  Board b("");
  ASSERT_TRUE(b.ok) << b.why;
  const lode::Elements& signals = b.h.output_elements("signals");
  ASSERT_EQ(signals.size(), 4u);
  EXPECT_EQ(signals[0].name, "A_a");
  EXPECT_EQ(signals[0].unit, "V");
  EXPECT_EQ(signals[3].name, "B_b");
  const lode::Elements& counts = b.h.output_elements("counts");
  ASSERT_EQ(counts.size(), 4u);
  EXPECT_EQ(counts[1].name, "A_b");
  EXPECT_EQ(counts[1].unit, "1");
  const lode::Elements& truth = b.h.output_elements("truth");
  ASSERT_EQ(truth.size(), 3u);
  EXPECT_EQ(truth[2].name, "theta_z");
  EXPECT_EQ(b.h.output_elements("plant_state").size(), 6u);
  EXPECT_EQ(b.h.output_elements("plant_state")[5].name, "omega_z");
}

// Several models: channels are concatenated in the order of `sensors`; each sees the pose.
TEST(IoSim, SensorListConcatenatesChannelsInOrder) {
  REQUIRE_HALBACH();
  const std::string models =
      "stage: {plugin: plant.planar_stage, initial: [0.003, -0.002, 0.01]}\n"
      "hall_a: {plugin: sensor.halbach_hall, sensors: [{name: A, x_m: 0.00635, y_m: 0.09525}]}\n"
      "hall_b: {plugin: sensor.halbach_hall, sensors: [{name: B, x_m: -0.00635, y_m: -0.09525}]}\n"
      "both: {plugin: sensor.halbach_hall, sensors: [{name: A, x_m: 0.00635, y_m: 0.09525}, "
      "{name: B, x_m: -0.00635, y_m: -0.09525}]}\n";
  BlockHarness split("io.sim", "plant: stage\nsensors: [hall_b, hall_a]\nnoise_std_v: 0\n",
                     kRateHz, models);
  BlockHarness joint("io.sim", "plant: stage\nsensors: [both]\nnoise_std_v: 0\n", kRateHz, models);
  for (BlockHarness* h : {&split, &joint}) {
    h->feed("command", kCommand);
    ASSERT_TRUE(h->configure()) << h->diagnostics();
    ASSERT_TRUE(h->activate());
    h->step();
  }
  const lode::Elements& names = split.output_elements("signals");
  ASSERT_EQ(names.size(), 4u);
  EXPECT_EQ(names[0].name, "B_a");
  EXPECT_EQ(names[1].name, "B_b");
  EXPECT_EQ(names[2].name, "A_a");
  EXPECT_EQ(names[3].name, "A_b");
  // The same sensors evaluated at the same (non-zero) pose give the same volts.
  EXPECT_EQ(split.output("signals")[0], joint.output("signals")[2]);
  EXPECT_EQ(split.output("signals")[1], joint.output("signals")[3]);
  EXPECT_EQ(split.output("signals")[2], joint.output("signals")[0]);
  EXPECT_EQ(split.output("signals")[3], joint.output("signals")[1]);
  EXPECT_EQ(split.describe().find("sensors")->elements().size(), 2u);
}

// Cycle k's command is applied in its write phase; the plant sampled in cycle k+1 has moved
// by exactly a dt^2/2 (from rest), and not at all in cycle k.
TEST(IoSim, CommandOfCycleKMovesTheSampleOfCycleKPlusOne) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 0\n");
  ASSERT_TRUE(b.ok) << b.why;
  auto command = b.h.input("command");
  command[0] = 3.1;
  command[1] = -6.2;
  command[2] = 0.027;
  ASSERT_EQ(b.h.step(), StepStatus::ok);  // cycle 0: read
  const std::vector<double> truth0 = copy(b.h.output("truth"));
  EXPECT_EQ(truth0, (std::vector<double>{0.0, 0.0, 0.0})) << "the command is not applied yet";
  ASSERT_EQ(b.h.write(), StepStatus::ok);  // cycle 0: write -> plant advances
  ASSERT_EQ(b.h.step(), StepStatus::ok);   // cycle 1: read
  const double half_dt2 = 0.5 * kDt * kDt;
  EXPECT_DOUBLE_EQ(b.h.output("truth")[0], 3.1 / kMassKg * half_dt2);
  EXPECT_DOUBLE_EQ(b.h.output("truth")[1], -6.2 / kMassKg * half_dt2);
  EXPECT_DOUBLE_EQ(b.h.output("truth")[2], 0.027 / 0.054 * half_dt2);
  EXPECT_DOUBLE_EQ(b.h.output("plant_state")[3], 3.1 / kMassKg * kDt);
  EXPECT_DOUBLE_EQ(b.h.output("plant_state")[5], 0.027 / 0.054 * kDt);
  EXPECT_EQ(b.h.output("plant_state")[0], b.h.output("truth")[0]);

  // The second cycle under the same held command: p = a (2 dt)^2 / 2.
  ASSERT_EQ(b.h.write(), StepStatus::ok);
  ASSERT_EQ(b.h.step(), StepStatus::ok);
  EXPECT_NEAR(b.h.output("truth")[0], 3.1 / kMassKg * 0.5 * (2 * kDt) * (2 * kDt), 1e-20);
}

// Signals of a noise-free board equal the sensor model's prediction at the true pose, so a
// moved plant changes them (the measurement chain really samples the plant).
TEST(IoSim, SignalsFollowTheMovingPlant) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 0\nadc_bits: 0\n");
  ASSERT_TRUE(b.ok) << b.why;
  auto command = b.h.input("command");
  b.h.step();
  const std::vector<double> at_rest = copy(b.h.output("signals"));
  command[1] = 50.0;  // Y force: the "a" channels (world Y field) change
  for (int k = 0; k < 80; ++k) {
    b.h.write();
    b.h.step();
  }
  const std::vector<double> moved = copy(b.h.output("signals"));
  const double y = b.h.output("truth")[1];
  EXPECT_NEAR(y, 0.5 * 50.0 / kMassKg * (80 * kDt) * (80 * kDt), 1e-12);
  EXPECT_GT(std::abs(moved[0] - at_rest[0]), 1e-3) << "A_a must see the Y motion";
  EXPECT_NEAR(moved[1], at_rest[1], 1e-12) << "A_b sees world X only, which did not move";
}

TEST(IoSim, WhiteNoiseStdWithinFivePercent) {
  REQUIRE_HALBACH();
  int seed = 11;
  for (const double sigma : {1e-3, 5e-3}) {
    Board b("noise_std_v: " + std::to_string(sigma) + "\nadc_bits: 0\nseed: " +
            std::to_string(seed++) + "\n");
    ASSERT_TRUE(b.ok) << b.why;
    Board clean("noise_std_v: 0\nadc_bits: 0\n");
    ASSERT_TRUE(clean.ok) << clean.why;
    clean.h.step();
    const std::vector<double> truth_signals = copy(clean.h.output("signals"));
    constexpr int kSamples = 20000;
    std::vector<double> sum(4, 0.0), sum_sq(4, 0.0);
    for (int k = 0; k < kSamples; ++k) {
      b.h.step();
      b.h.write();
      for (std::size_t c = 0; c < 4; ++c) {
        const double e = b.h.output("signals")[c] - truth_signals[c];
        sum[c] += e;
        sum_sq[c] += e * e;
      }
    }
    for (std::size_t c = 0; c < 4; ++c) {
      const double mean = sum[c] / kSamples;
      const double std = std::sqrt(sum_sq[c] / kSamples - mean * mean);
      EXPECT_NEAR(std / sigma, 1.0, 0.05) << "channel " << c << " sigma " << sigma;
      EXPECT_NEAR(mean, 0.0, 5.0 * sigma / std::sqrt(kSamples)) << "channel " << c;
      std::printf("noise sigma %.1e V, channel %zu: measured std %.4e V (ratio %.4f)\n", sigma, c,
                  std, std / sigma);
    }
  }
}

TEST(IoSim, QuantizationStepIsTwiceRangeOverTwoToTheBits) {
  REQUIRE_HALBACH();
  // 12 bits over +-10 V: LSB = 20 V / 4096 = 4.8828125 mV (an example; the thesis gives no ADC range).
  Board b("noise_std_v: 0.02\nadc_bits: 12\nadc_range_v: 10\n");
  ASSERT_TRUE(b.ok) << b.why;
  const double lsb = 2.0 * 10.0 / 4096.0;
  const lode::Json d = b.h.describe();
  EXPECT_EQ(json_number(d, "lsb_v"), lsb);
  EXPECT_NEAR(json_number(d, "quantization_noise_std_v"), lsb / std::sqrt(12.0), 1e-15);
  EXPECT_NEAR(json_number(d, "total_noise_std_v"), std::sqrt(0.02 * 0.02 + lsb * lsb / 12.0), 1e-15);

  std::vector<std::set<double>> levels(4);
  for (int k = 0; k < 4000; ++k) {
    b.h.step();
    b.h.write();
    for (std::size_t c = 0; c < 4; ++c) {
      const double count = b.h.output("counts")[c];
      ASSERT_EQ(count, std::round(count)) << "counts are integers";
      ASSERT_EQ(b.h.output("signals")[c], count * lsb) << "volts = counts * LSB exactly";
      levels[c].insert(b.h.output("signals")[c]);
    }
  }
  for (std::size_t c = 0; c < 4; ++c) {
    ASSERT_GE(levels[c].size(), 10u) << "20 mV of noise spans many 4.9 mV codes";
    double smallest_step = 1e9;
    for (auto it = std::next(levels[c].begin()); it != levels[c].end(); ++it)
      smallest_step = std::min(smallest_step, *it - *std::prev(it));
    EXPECT_NEAR(smallest_step, lsb, 1e-15) << "channel " << c;
  }

  // Noise-free: the quantized value is within half an LSB of the ideal one.
  Board ideal("noise_std_v: 0\nadc_bits: 0\n");
  Board coarse("noise_std_v: 0\nadc_bits: 12\n");
  ASSERT_TRUE(ideal.ok && coarse.ok);
  ideal.h.step();
  coarse.h.step();
  for (std::size_t c = 0; c < 4; ++c)
    EXPECT_LE(std::abs(coarse.h.output("signals")[c] - ideal.h.output("signals")[c]), 0.5 * lsb);
}

TEST(IoSim, SaturationClipsToTheCodeRangeAndIsCounted) {
  REQUIRE_HALBACH();
  // The Hall channels swing about +-3 V; a +-1 V, 8-bit converter must clip some of them.
  Board ideal("noise_std_v: 0\nadc_bits: 0\n");
  Board b("noise_std_v: 0\nadc_bits: 8\nadc_range_v: 1\n");
  ASSERT_TRUE(ideal.ok && b.ok) << ideal.why << b.why;
  ideal.h.step();
  b.h.step();
  const double lsb = 2.0 / 256.0;
  int clipped = 0;
  for (std::size_t c = 0; c < 4; ++c) {
    const double v = ideal.h.output("signals")[c];
    const double count = b.h.output("counts")[c];
    EXPECT_GE(count, -128.0);
    EXPECT_LE(count, 127.0);
    if (v >= 127.5 * lsb) {
      EXPECT_EQ(count, 127.0);
      ++clipped;
    } else if (v < -128.5 * lsb) {
      EXPECT_EQ(count, -128.0);
      ++clipped;
    }
  }
  ASSERT_GT(clipped, 0) << "test premise: some channel exceeds +-1 V at the origin";
  EXPECT_EQ(json_number(b.h.describe(), "adc_saturations"), clipped);
}

// Mains interference: project the residual on sin/cos to recover amplitude and phase, and
// scan the projection over frequency to recover 60 Hz (with 1 mV white noise present).
TEST(IoSim, MainsAmplitudeFrequencyAndPhaseAreRecovered) {
  REQUIRE_HALBACH();
  const double amplitude = 5e-3, frequency = 60.0, phase = 0.3;
  Board b("noise_std_v: 1e-3\nadc_bits: 0\nmains_amplitude_v: 5e-3\nmains_frequency_hz: 60\n"
          "mains_phase_rad: 0.3\n");
  Board clean("noise_std_v: 0\nadc_bits: 0\n");
  ASSERT_TRUE(b.ok && clean.ok) << b.why << clean.why;
  clean.h.step();
  const double base = clean.h.output("signals")[2];
  constexpr int kSamples = 8000;  // 10 s: 0.1 Hz resolution, 600 mains periods
  std::vector<double> residual(kSamples), time_s(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    b.h.step();
    b.h.write();
    residual[k] = b.h.output("signals")[2] - base;
    time_s[k] = static_cast<double>(b.h.tick().time_ns) * 1e-9;
  }
  auto project = [&](double f, double& s, double& c) {
    s = c = 0.0;
    for (int k = 0; k < kSamples; ++k) {
      s += residual[k] * std::sin(2 * std::numbers::pi * f * time_s[k]);
      c += residual[k] * std::cos(2 * std::numbers::pi * f * time_s[k]);
    }
    s *= 2.0 / kSamples;
    c *= 2.0 / kSamples;
  };
  double s = 0, c = 0;
  project(frequency, s, c);
  // A sin(wt + phi) = A cos(phi) sin(wt) + A sin(phi) cos(wt)
  const double recovered_amplitude = std::hypot(s, c);
  const double recovered_phase = std::atan2(c, s);
  std::printf("mains: amplitude %.6e V (set %.1e), phase %.5f rad (set %.2f)\n",
              recovered_amplitude, amplitude, recovered_phase, phase);
  // Noise leaks sigma*sqrt(2/N) = 16 uV into each projection: 2 % and 0.02 rad are 6 sigma.
  EXPECT_NEAR(recovered_amplitude, amplitude, 0.02 * amplitude);
  EXPECT_NEAR(recovered_phase, phase, 0.02);

  double best_f = 0.0, best = 0.0;
  for (double f = 40.0; f <= 80.0 + 1e-9; f += 0.1) {
    project(f, s, c);
    if (std::hypot(s, c) > best) {
      best = std::hypot(s, c);
      best_f = f;
    }
  }
  std::printf("mains: spectral peak at %.2f Hz\n", best_f);
  EXPECT_NEAR(best_f, frequency, 0.05);
}

TEST(IoSim, ChannelOffsetsAreAddedPerChannel) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 0\nadc_bits: 0\nchannel_offset_v: [0.01, -0.02, 0.003, 0]\n");
  Board clean("noise_std_v: 0\nadc_bits: 0\n");
  ASSERT_TRUE(b.ok && clean.ok) << b.why << clean.why;
  b.h.step();
  clean.h.step();
  const double offsets[] = {0.01, -0.02, 0.003, 0.0};
  for (std::size_t c = 0; c < 4; ++c)
    EXPECT_NEAR(b.h.output("signals")[c] - clean.h.output("signals")[c], offsets[c], 1e-15);
}

TEST(IoSim, SameSeedGivesBitIdenticalSignals) {
  REQUIRE_HALBACH();
  const std::string params = "noise_std_v: 1e-3\nmains_amplitude_v: 1e-3\nseed: 1234\n";
  Board first(params), second(params), other("noise_std_v: 1e-3\nmains_amplitude_v: 1e-3\nseed: 1235\n");
  ASSERT_TRUE(first.ok && second.ok && other.ok);
  int differing_from_other = 0;
  for (Board* b : {&first, &second, &other}) b->h.input("command")[0] = 0.5;
  for (int k = 0; k < 2000; ++k) {
    for (Board* b : {&first, &second, &other}) {
      b->h.step();
      b->h.write();
    }
    for (std::size_t c = 0; c < 4; ++c) {
      ASSERT_EQ(first.h.output("signals")[c], second.h.output("signals")[c]) << "cycle " << k;
      ASSERT_EQ(first.h.output("counts")[c], second.h.output("counts")[c]) << "cycle " << k;
      if (first.h.output("counts")[c] != other.h.output("counts")[c]) ++differing_from_other;
    }
  }
  EXPECT_GT(differing_from_other, 4000) << "another seed gives other noise";
}

TEST(IoSim, ReactivationReplaysTheSameSequence) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 1e-3\nseed: 99\n");
  ASSERT_TRUE(b.ok);
  std::vector<double> first_run;
  for (int k = 0; k < 50; ++k) {
    b.h.step();
    first_run.push_back(b.h.output("counts")[0]);
  }
  ASSERT_TRUE(b.h.activate());
  for (int k = 0; k < 50; ++k) {
    b.h.step();
    EXPECT_EQ(b.h.output("counts")[0], first_run[static_cast<std::size_t>(k)]) << "sample " << k;
  }
}

TEST(IoSim, NonFiniteCommandFaultsAndDrivesSafe) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 0\nsafe_command: [0.62, 0, 0]\n");
  ASSERT_TRUE(b.ok) << b.why;
  auto command = b.h.input("command");
  command[0] = 1.0;
  b.h.step();
  ASSERT_EQ(b.h.write(), StepStatus::ok);
  b.h.step();
  const double x1 = b.h.output("truth")[0];
  const double v1 = b.h.output("plant_state")[3];
  command[1] = std::nan("");
  EXPECT_EQ(b.h.write(), StepStatus::fault);
  EXPECT_STREQ(b.h.block().fault_reason(), "non-finite command");
  EXPECT_EQ(b.h.describe().find("safe")->as_bool(), true);
  // The fault cycle already ran under the safe command (0.62 N / 6.2 kg = 0.1 m/s^2) ...
  b.h.step();
  EXPECT_NEAR(b.h.output("plant_state")[3] - v1, 0.1 * kDt, 1e-15);
  EXPECT_NEAR(b.h.output("truth")[0] - x1, v1 * kDt + 0.05 * kDt * kDt, 1e-18);
  EXPECT_EQ(b.h.output("truth")[1], 0.0) << "the NaN never reached the plant";
  // ... and the safe command stays latched though the command is valid again.
  command[0] = 100.0;
  command[1] = 0.0;
  const double v2 = b.h.output("plant_state")[3];
  ASSERT_EQ(b.h.write(), StepStatus::ok);
  b.h.step();
  EXPECT_NEAR(b.h.output("plant_state")[3] - v2, 0.1 * kDt, 1e-15);

  // activate() clears the latch and resets the plant (the pipeline zeroes every signal).
  ASSERT_TRUE(b.h.activate());
  EXPECT_EQ(b.h.describe().find("safe")->as_bool(), false);
  EXPECT_EQ(b.h.output("truth")[0], 0.0);
  command[0] = 100.0;
  b.h.step();
  b.h.write();
  b.h.step();
  EXPECT_NEAR(b.h.output("plant_state")[3], 100.0 / kMassKg * kDt, 1e-12);
}

TEST(IoSim, InfiniteCommandAlsoFaults) {
  REQUIRE_HALBACH();
  Board b("");
  ASSERT_TRUE(b.ok);
  b.h.input("command")[2] = -HUGE_VAL;
  b.h.step();
  EXPECT_EQ(b.h.write(), StepStatus::fault);
  EXPECT_TRUE(b.h.describe().find("safe")->as_bool());
}

TEST(IoSim, CommandLimitClampsAndCounts) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 0\ncommand_limit: [2, 2, 0.01]\n");
  ASSERT_TRUE(b.ok) << b.why;
  auto command = b.h.input("command");
  command[0] = 10.0;   // clamped to 2
  command[1] = -1.5;   // inside
  command[2] = -0.5;   // clamped to -0.01
  b.h.step();
  b.h.write();
  b.h.step();
  EXPECT_DOUBLE_EQ(b.h.output("plant_state")[3], 2.0 / kMassKg * kDt);
  EXPECT_DOUBLE_EQ(b.h.output("plant_state")[4], -1.5 / kMassKg * kDt);
  EXPECT_DOUBLE_EQ(b.h.output("plant_state")[5], -0.01 / 0.054 * kDt);
  EXPECT_EQ(json_number(b.h.describe(), "command_clamps"), 2.0);
}

TEST(IoSim, SubstepsDoNotChangeAnExactPlant) {
  REQUIRE_HALBACH();
  Board one("noise_std_v: 0\n"), many("noise_std_v: 0\nsubsteps: 7\n");
  ASSERT_TRUE(one.ok && many.ok) << many.why;
  for (Board* b : {&one, &many}) {
    b->h.input("command")[0] = 1.3;
    b->h.input("command")[2] = -0.01;
    for (int k = 0; k < 400; ++k) {
      b->h.step();
      b->h.write();
    }
    b->h.step();
  }
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_NEAR(one.h.output("plant_state")[i], many.h.output("plant_state")[i], 1e-14) << i;
}

TEST(IoSim, DescribeReportsTheChain) {
  REQUIRE_HALBACH();
  Board b("noise_std_v: 1e-3\nadc_bits: 16\nadc_range_v: 10\nmains_amplitude_v: 2e-3\n");
  ASSERT_TRUE(b.ok);
  const lode::Json d = b.h.describe();
  const double lsb = 20.0 / 65536.0;
  EXPECT_EQ(json_number(d, "lsb_v"), lsb);
  EXPECT_NEAR(json_number(d, "total_noise_std_v"),
              std::sqrt(1e-6 + lsb * lsb / 12.0 + 2e-3 * 2e-3 / 2.0), 1e-15);
  EXPECT_EQ(json_number(d, "count_max"), 32767.0);
  EXPECT_EQ(json_number(d, "count_min"), -32768.0);
  ASSERT_NE(d.find("plant"), nullptr);
  EXPECT_EQ(d.find("plant")->as_string(), "stage");
  ASSERT_NE(d.find("sensors"), nullptr);
  EXPECT_EQ(d.find("sensors")->elements().size(), 1u);
}

// ---- Configuration errors: located, named, all reported. ----------------------------------

std::string configure_error(const std::string& params, const std::string& models = kModels) {
  BlockHarness h("io.sim", params, kRateHz, models);
  h.feed("command", kCommand);
  const lode::Status st = h.configure();
  return st ? std::string("(configured)") : h.diagnostics();
}

TEST(IoSimConfig, UnknownModelNamesAreLocatedErrors) {
  REQUIRE_HALBACH();
  const std::string d = configure_error("plant: nope\nsensors: hall\n");
  EXPECT_NE(d.find("blocks.dut.plant: no model named 'nope'"), std::string::npos) << d;
  EXPECT_NE(d.find(":"), std::string::npos);
  const std::string d2 = configure_error("plant: stage\nsensors: missing_hall\n");
  EXPECT_NE(d2.find("blocks.dut.sensors: no model named 'missing_hall'"), std::string::npos) << d2;
  // A plant where a sensor is needed (and vice versa) is refused with the kinds named.
  const std::string d3 = configure_error("plant: hall\nsensors: stage\n");
  EXPECT_NE(d3.find("blocks.dut.plant: model 'hall' is a sensor"), std::string::npos) << d3;
  EXPECT_NE(d3.find("blocks.dut.sensors: model 'stage' is a plant"), std::string::npos) << d3;
}

TEST(IoSimConfig, DuplicateChannelNamesAreRefused) {
  REQUIRE_HALBACH();
  const std::string d = configure_error("plant: stage\nsensors: [hall, hall]\n");
  EXPECT_NE(d.find("blocks.dut.sensors: channel 'A_a' of sensor model 'hall' is also produced "
                   "by an earlier sensor"),
            std::string::npos)
      << d;
}

TEST(IoSimConfig, InvalidValuesAreReportedTogether) {
  REQUIRE_HALBACH();
  const std::string d = configure_error(
      "plant: stage\nsensors: hall\nnoise_std_v: -1\nadc_bits: 1\nadc_range_v: 0\n"
      "mains_amplitude_v: -2\nchannel_offset_v: [1, 2]\nsafe_command: [0, 0]\n"
      "command_limit: [1, 0, 1]\nsubsteps: 0\n");
  for (const char* expected :
       {"blocks.dut.noise_std_v: must be >= 0 V, got -1", "blocks.dut.adc_bits: must be 0",
        "blocks.dut.adc_range_v: must be > 0 V", "blocks.dut.mains_amplitude_v: must be >= 0 V",
        "blocks.dut.channel_offset_v: expected 4 numbers, got 2",
        "blocks.dut.safe_command: expected 3 numbers, got 2",
        "blocks.dut.command_limit: every limit must be > 0, got 0 for fy",
        "blocks.dut.substeps: must be within 1"}) {
    EXPECT_NE(d.find(expected), std::string::npos) << "missing: " << expected << "\n" << d;
  }
}

TEST(IoSimConfig, SafeCommandOutsideTheLimitIsRefused) {
  REQUIRE_HALBACH();
  const std::string d = configure_error(
      "plant: stage\nsensors: hall\nsafe_command: [5, 0, 0]\ncommand_limit: [1, 1, 1]\n");
  EXPECT_NE(d.find("blocks.dut.safe_command: safe value 5 for fx exceeds command_limit 1"),
            std::string::npos)
      << d;
}

TEST(IoSimConfig, MissingPlantAndSensorsAreReported) {
  const std::string d = configure_error("noise_std_v: 1e-3\n", "");
  EXPECT_NE(d.find("blocks.dut.plant: missing required parameter 'plant'"), std::string::npos) << d;
  EXPECT_NE(d.find("blocks.dut.sensors"), std::string::npos) << d;
}

// The harness's test feeds are not unit-checked by the loader, so the command's units are
// checked in a real pipeline: a reference block drives the board open loop.
std::string open_loop_pipeline(const std::string& units) {
  return "pipeline: open_loop\nrate_hz: 800\n"
         "models:\n"
         "  stage: {plugin: plant.planar_stage}\n"
         "  hall: " + kHallSpec + "\n" +
         "blocks:\n"
         "  board: {plugin: io.sim, plant: stage, sensors: hall, noise_std_v: 0,"
         " inputs: {command: force.out}}\n"
         "  force: {plugin: source.step, names: [fx, fy, tz], units: " + units +
         ", steps: [{time_s: 0, value: [0.62, 0, 0]}]}\n";
}

TEST(IoSimPipeline, CommandUnitsAreChecked) {
  REQUIRE_HALBACH();
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  auto pipeline = lode::Pipeline::load_text(open_loop_pipeline("[N, N, N]"), "<open_loop>",
                                            registry, diagnostics);
  EXPECT_EQ(pipeline, nullptr);
  EXPECT_NE(diagnostics.format().find("blocks.board.inputs.command: unit mismatch at element 2"),
            std::string::npos)
      << diagnostics.format();
}

// io.read -> force -> io.write each cycle: after n cycles the plant has had n writes, so the
// sample of cycle n shows a (n dt)^2 / 2.
TEST(IoSimPipeline, OpenLoopCycleOrder) {
  REQUIRE_HALBACH();
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  auto pipeline = lode::Pipeline::load_text(open_loop_pipeline("[N, N, N*m]"), "<open_loop>",
                                            registry, diagnostics);
  ASSERT_NE(pipeline, nullptr) << diagnostics.format();
  ASSERT_TRUE(pipeline->activate());
  const auto truth = pipeline->signal("board.truth");
  ASSERT_TRUE(truth.has_value());
  lode::Tick tick;
  tick.dt_s = kDt;
  constexpr int kCycles = 400;
  for (int k = 0; k <= kCycles; ++k) {
    tick.cycle = static_cast<std::uint64_t>(k);
    tick.time_ns = static_cast<std::int64_t>(k) * 1'250'000;
    ASSERT_EQ(pipeline->run_cycle(tick, false).status, StepStatus::ok);
    const double t = k * kDt;
    ASSERT_NEAR(truth->data[0], 0.5 * (0.62 / kMassKg) * t * t, 1e-15) << "cycle " << k;
  }
  pipeline->deactivate();
}

// ---- Real-time contract: no allocation in the cycle. ---------------------------------------

TEST(IoSimRealtime, CycleDoesNotAllocate) {
  REQUIRE_HALBACH();
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Board b("noise_std_v: 1e-3\nmains_amplitude_v: 1e-3\ncommand_limit: [5, 5, 0.1]\nsubsteps: 3\n");
  ASSERT_TRUE(b.ok) << b.why;
  auto command = b.h.input("command");  // name lookups allocate: done before counting
  BlockHarness& h = b.h;
  const long before = static_cast<long>(lode::testing::allocation_count());
  for (int k = 0; k < 10000; ++k) {
    command[0] = std::sin(k * 0.01);
    command[2] = 0.2 * std::cos(k * 0.01);  // sometimes clamped
    h.step();
    h.write();
  }
  const long during = static_cast<long>(lode::testing::allocation_count()) - before;
  EXPECT_EQ(during, 0) << "allocations in 10000 read/write cycles";
}

// --- fault injection (the health monitor's NaN trip) ---------------------------

constexpr std::int64_t kWindowStartNs = 10'000'000;  // start_s: 0.01
constexpr std::int64_t kWindowEndNs = 15'000'000;    // + duration_s: 0.005

TEST(IoSimInject, YamlWindowMakesOneChannelNaNExactlyInTheWindow) {
  REQUIRE_HALBACH();
  const std::string chain = "noise_std_v: 1e-3\nmains_amplitude_v: 1e-3\nseed: 99\n";
  Board injected(chain + "inject_nan: {channel: A_b, start_s: 0.01, duration_s: 0.005}\n");
  Board reference(chain);
  ASSERT_TRUE(injected.ok) << injected.why;
  ASSERT_TRUE(reference.ok) << reference.why;
  int nan_cycles = 0;
  for (int k = 0; k < 40; ++k) {
    for (Board* b : {&injected, &reference}) {
      b->h.input("command")[0] = 0.3;
      ASSERT_EQ(b->h.step(), StepStatus::ok);
      b->h.write();
    }
    const std::int64_t t = injected.h.tick().time_ns;
    const bool in_window = t >= kWindowStartNs && t < kWindowEndNs;
    for (std::size_t c = 0; c < 4; ++c) {
      const double signal = injected.h.output("signals")[c];
      const double count = injected.h.output("counts")[c];
      if (c == 1 && in_window) {
        EXPECT_TRUE(std::isnan(signal)) << "cycle " << k;
        EXPECT_TRUE(std::isnan(count)) << "cycle " << k;
      } else {
        // Everything else is bit for bit the board without injection (same noise draws).
        ASSERT_EQ(signal, reference.h.output("signals")[c]) << "cycle " << k << " channel " << c;
        ASSERT_EQ(count, reference.h.output("counts")[c]) << "cycle " << k << " channel " << c;
      }
    }
    if (std::isnan(injected.h.output("signals")[1])) ++nan_cycles;
  }
  // 800 Hz: t = 10, 11.25, 12.5, 13.75 ms are in [10, 15) ms; 15 ms is not.
  EXPECT_EQ(nan_cycles, 4);
  const lode::Json d = injected.h.describe();
  ASSERT_NE(d.find("inject_nan"), nullptr);
  EXPECT_EQ(json_number(*d.find("inject_nan"), "channel_index"), 1.0);
}

TEST(IoSimInject, TunableInjectsLiveAndTurnsOff) {
  REQUIRE_HALBACH();
  Board injected("seed: 5\n");
  Board reference("seed: 5\n");
  ASSERT_TRUE(injected.ok && reference.ok) << injected.why;
  lode::Tunables& block = injected.h.tunables();
  const std::vector<lode::Tunable> tunables = block.tunables();
  ASSERT_EQ(tunables.size(), 1u);
  EXPECT_EQ(tunables[0].name, "inject_nan_channel");
  EXPECT_EQ(tunables[0].min, -1.0);
  EXPECT_EQ(tunables[0].max, 3.0);
  EXPECT_TRUE(tunables[0].integer);
  EXPECT_EQ(block.tunable_value(0), -1.0) << "off by default";
  const char* why = "";
  for (double refused : {4.0, -2.0, 0.5}) {
    EXPECT_FALSE(block.set_tunable(0, refused, why)) << refused;
    EXPECT_EQ(block.tunable_value(0), -1.0);
  }
  auto cycle = [&](int k) {
    for (Board* b : {&injected, &reference}) {
      ASSERT_EQ(b->h.step(), StepStatus::ok);
      b->h.write();
    }
    for (std::size_t c = 0; c < 4; ++c) {
      const bool nan_expected = k >= 10 && k < 20 && c == 2;
      if (nan_expected) {
        EXPECT_TRUE(std::isnan(injected.h.output("signals")[c])) << k;
        EXPECT_TRUE(std::isnan(injected.h.output("counts")[c])) << k;
      } else {
        ASSERT_EQ(injected.h.output("signals")[c], reference.h.output("signals")[c]) << k << " " << c;
        ASSERT_EQ(injected.h.output("counts")[c], reference.h.output("counts")[c]) << k << " " << c;
      }
    }
  };
  for (int k = 0; k < 10; ++k) cycle(k);
  ASSERT_TRUE(block.set_tunable(0, 2.0, why)) << why;  // lode set stage.inject_nan_channel 2
  EXPECT_EQ(block.tunable_value(0), 2.0);
  for (int k = 10; k < 20; ++k) cycle(k);
  ASSERT_TRUE(block.set_tunable(0, -1.0, why)) << why;
  for (int k = 20; k < 30; ++k) cycle(k);
}

TEST(IoSimInject, ConfigurationErrorsAreLocated) {
  REQUIRE_HALBACH();
  Board unknown("inject_nan: {channel: C_a, start_s: 0.1, duration_s: 0.1}\n");
  EXPECT_FALSE(unknown.ok);
  EXPECT_NE(unknown.why.find("no channel 'C_a'"), std::string::npos) << unknown.why;
  EXPECT_NE(unknown.why.find("A_a, A_b, B_a, B_b"), std::string::npos) << unknown.why;
  Board bad("inject_nan: {channel: A_a, start_s: -1, duration_s: 0}\n");
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.why.find("start_s"), std::string::npos) << bad.why;
  EXPECT_NE(bad.why.find("duration_s"), std::string::npos) << bad.why;
  Board missing("inject_nan: {channel: A_a}\n");
  EXPECT_FALSE(missing.ok);
  EXPECT_NE(missing.why.find("start_s"), std::string::npos) << missing.why;
}

// A stuck channel: finite, so a NaN check misses it (the health monitor's innovation test).

/// Runs an injected and a reference board side by side for 40 cycles at 800 Hz; `check`
/// sees cycle k, whether it is in the [10, 15) ms window, and both boards.
void side_by_side(const std::string& injection, const std::function<void(int, bool, Board&, Board&)>& check) {
  const std::string chain = "noise_std_v: 1e-3\nmains_amplitude_v: 1e-3\nseed: 99\n";
  Board injected(chain + injection);
  Board reference(chain);
  ASSERT_TRUE(injected.ok) << injected.why;
  ASSERT_TRUE(reference.ok) << reference.why;
  for (int k = 0; k < 40; ++k) {
    for (Board* b : {&injected, &reference}) {
      b->h.input("command")[0] = 0.3;
      ASSERT_EQ(b->h.step(), StepStatus::ok);
      b->h.write();
    }
    const std::int64_t t = injected.h.tick().time_ns;
    check(k, t >= kWindowStartNs && t < kWindowEndNs, injected, reference);
  }
}

TEST(IoSimInject, StuckChannelReadsItsValueThroughTheConverterInTheWindow) {
  REQUIRE_HALBACH();
  const double lsb = 20.0 / 65536.0;  // 16 bits over +-10 V
  int stuck_cycles = 0;
  side_by_side("inject_stuck: {channel: A_b, start_s: 0.01, duration_s: 0.005, value_v: 0.3}\n",
               [&](int k, bool in_window, Board& injected, Board& reference) {
                 for (std::size_t c = 0; c < 4; ++c) {
                   const double signal = injected.h.output("signals")[c];
                   const double count = injected.h.output("counts")[c];
                   if (c == 1 && in_window) {
                     EXPECT_EQ(count, std::floor(0.3 / lsb + 0.5)) << "cycle " << k;
                     EXPECT_EQ(signal, count * lsb) << "cycle " << k;
                     ++stuck_cycles;
                   } else {
                     // Everything else is bit for bit the board without injection (same noise draws).
                     ASSERT_EQ(signal, reference.h.output("signals")[c]) << "cycle " << k << " channel " << c;
                     ASSERT_EQ(count, reference.h.output("counts")[c]) << "cycle " << k << " channel " << c;
                   }
                 }
                 if (k == 39) {
                   const lode::Json d = injected.h.describe();
                   ASSERT_NE(d.find("inject_stuck"), nullptr);
                   EXPECT_EQ(json_number(*d.find("inject_stuck"), "channel_index"), 1.0);
                   EXPECT_EQ(json_number(*d.find("inject_stuck"), "value_v"), std::floor(0.3 / lsb + 0.5) * lsb);
                 }
               });
  EXPECT_EQ(stuck_cycles, 4);  // t = 10, 11.25, 12.5, 13.75 ms
}

TEST(IoSimInject, StuckChannelWithoutValueHoldsItsLastReadingBeforeTheWindow) {
  REQUIRE_HALBACH();
  double held_signal = std::nan("");
  double held_count = std::nan("");
  int stuck_cycles = 0;
  side_by_side("inject_stuck: {channel: B_a, start_s: 0.01, duration_s: 0.005}\n",
               [&](int k, bool in_window, Board& injected, Board& reference) {
                 const double signal = injected.h.output("signals")[2];
                 const double count = injected.h.output("counts")[2];
                 if (in_window) {
                   EXPECT_EQ(signal, held_signal) << "cycle " << k;
                   EXPECT_EQ(count, held_count) << "cycle " << k;
                   ++stuck_cycles;
                 } else {
                   ASSERT_EQ(signal, reference.h.output("signals")[2]) << "cycle " << k;
                   ASSERT_EQ(count, reference.h.output("counts")[2]) << "cycle " << k;
                   held_signal = signal;  // the frozen converter's last conversion
                   held_count = count;
                 }
               });
  EXPECT_EQ(stuck_cycles, 4);
}

TEST(IoSimInject, StuckValueOutsideTheRangeIsClippedLikeAnyReading) {
  REQUIRE_HALBACH();
  side_by_side("inject_stuck: {channel: A_a, start_s: 0.01, duration_s: 0.005, value_v: -25}\n",
               [&](int k, bool in_window, Board& injected, Board&) {
                 if (!in_window) return;
                 EXPECT_EQ(injected.h.output("counts")[0], -32768.0) << "cycle " << k;
                 EXPECT_EQ(injected.h.output("signals")[0], -10.0) << "cycle " << k;
               });
}

TEST(IoSimInject, StuckConfigurationErrorsAreLocated) {
  REQUIRE_HALBACH();
  Board unknown("inject_stuck: {channel: C_a, start_s: 0.1, duration_s: 0.1, value_v: 0}\n");
  EXPECT_FALSE(unknown.ok);
  EXPECT_NE(unknown.why.find("no channel 'C_a'"), std::string::npos) << unknown.why;
  Board missing("inject_stuck: {channel: A_a, value_v: 0}\n");
  EXPECT_FALSE(missing.ok);
  EXPECT_NE(missing.why.find("start_s"), std::string::npos) << missing.why;
  EXPECT_NE(missing.why.find("duration_s"), std::string::npos) << missing.why;
}

TEST(IoSimInject, InjectionDoesNotAllocate) {
  REQUIRE_HALBACH();
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Board b("noise_std_v: 1e-3\ninject_nan: {channel: B_a, start_s: 0.5, duration_s: 1.0}\n"
          "inject_stuck: {channel: A_a, start_s: 1.0, duration_s: 1.0}\n");
  ASSERT_TRUE(b.ok) << b.why;
  const char* why = "";
  const long before = static_cast<long>(lode::testing::allocation_count());
  for (int k = 0; k < 4000; ++k) {
    if (k == 100) (void)b.h.tunables().set_tunable(0, 0.0, why);
    if (k == 3000) (void)b.h.tunables().set_tunable(0, -1.0, why);
    b.h.step();
    b.h.write();
  }
  EXPECT_EQ(static_cast<long>(lode::testing::allocation_count()) - before, 0);
}

}  // namespace
