// The envelope supervisor (`envelope:`): each kind of limit faults the cycle in which a value
// leaves it, with the outputs driven safe before the write phase and a message naming the
// value, the limit and the cycle; nothing inside trips; the check never allocates.
//
// The cause is always exactly predictable: a ramp crosses a bound at a computable cycle, a
// step jumps at a known cycle, a NaN window of io.sim starts at a known cycle. So each test
// asserts the fault cycle exactly, not "eventually".
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/hot_swap.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/sdk/testing/require.hpp"
#include "config_text.hpp"

namespace {

using lode::test::read_config;
using lode::test::read_file;
using lode::test::replace;

constexpr std::uint64_t kNever = ~std::uint64_t{0};

struct Outcome {
  bool loaded = false;
  std::string diagnostics;
  std::uint64_t fault_cycle = kNever;
  std::string fault;
  bool envelope = false;
  std::size_t allocations = 0;
};

/// Steps the pipeline like the scheduler's RT thread, up to `cycles` or the first fault.
Outcome run(const std::string& yaml, std::uint64_t cycles) {
  Outcome out;
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(yaml, "envelope.yaml", registry, diag);
  out.diagnostics = diag.format();
  if (!p) return out;
  out.loaded = true;
  lode::EventLog events;
  lode::HotSwap swapper(*p, events);  // the health monitor's fallback takes over through it
  EXPECT_TRUE(p->activate());
  swapper.set_running(true);
  for (std::uint64_t k = 0; k < cycles; ++k) {
    lode::Tick t;
    t.cycle = k;
    t.time_ns = static_cast<std::int64_t>(k) * p->period_ns();
    t.dt_s = 1.0 / p->rate_hz();
    const auto before = lode::testing::thread_allocation_count();
    swapper.before_cycle(t);
    const auto r = p->run_cycle(t, false);
    swapper.after_cycle(t);
    out.allocations += lode::testing::thread_allocation_count() - before;
    if (r.status != lode::StepStatus::ok) {
      out.fault_cycle = k;
      out.envelope = r.envelope;
      out.fault = r.envelope ? p->envelope_violation() : std::string();
      break;
    }
  }
  p->deactivate();
  return out;
}

/// A ramp of `rate` m/s from t = 0 at 1 kHz: out = k * rate mm at cycle k.
std::string ramp_pipeline(const std::string& envelope, double rate = 1.0) {
  char rate_text[32];
  std::snprintf(rate_text, sizeof rate_text, "%g", rate);
  return std::string("pipeline: envelope\nrate_hz: 1000\nblocks:\n") +
         "  ramp:\n    plugin: source.ramp\n    names: [x]\n    units: [m]\n    rate: [" + rate_text + "]\n" +
         "envelope:\n" + envelope;
}

TEST(Envelope, MaxAbsFaultsTheCycleThatCrossesIt) {
  LODE_REQUIRE_PLUGINS("source.ramp");
  LODE_REQUIRE_ALLOCATION_COUNTING();
  // |x| <= 0.0305 m: cycle 30 gives 30 mm (inside), cycle 31 gives 31 mm (outside).
  const Outcome r = run(ramp_pipeline("  ramp.out: { max_abs: [0.0305] }\n"), 100);
  ASSERT_TRUE(r.loaded) << r.diagnostics;
  EXPECT_EQ(r.fault_cycle, 31u) << r.fault;
  EXPECT_TRUE(r.envelope);
  EXPECT_NE(r.fault.find("envelope: ramp.out.x = 0.031 m is above its limit 0.0305 m (cycle 31"), std::string::npos)
      << r.fault;
  EXPECT_EQ(r.allocations, 0u) << "the envelope check allocated on the RT path";
}

TEST(Envelope, MinFaultsBelow) {
  LODE_REQUIRE_PLUGINS("source.ramp");
  const Outcome r = run(ramp_pipeline("  ramp.out: { min: [0.0] }\n", -1.0), 100);
  ASSERT_TRUE(r.loaded) << r.diagnostics;
  EXPECT_EQ(r.fault_cycle, 1u) << r.fault;  // cycle 0 gives 0 (inside), cycle 1 gives -1 mm
  EXPECT_NE(r.fault.find("is below its limit 0"), std::string::npos) << r.fault;
}

TEST(Envelope, MaxRateFaultsAJumpNotASlope) {
  LODE_REQUIRE_PLUGINS("source.step");
  // A step of 5 mm at t = 0.05 s (cycle 50 at 1 kHz): 5 m/s between two cycles, over the
  // 2 m/s limit; the constant before and after is at rate 0.
  const std::string yaml =
      "pipeline: envelope\nrate_hz: 1000\nblocks:\n"
      "  step:\n    plugin: source.step\n    names: [x]\n    units: [m]\n"
      "    steps: [{time_s: 0.05, value: [0.005]}]\n"
      "envelope:\n  step.out: { max_rate: [2.0] }\n";
  const Outcome r = run(yaml, 200);
  ASSERT_TRUE(r.loaded) << r.diagnostics;
  EXPECT_EQ(r.fault_cycle, 50u) << r.fault;
  EXPECT_NE(r.fault.find("changes at 5 m/s, faster than its limit 2 m/s"), std::string::npos) << r.fault;
  // Negative control: the same step under a 6 m/s limit runs through.
  const Outcome slow = run(yaml.substr(0, yaml.find("max_rate: [2.0]")) + "max_rate: [6.0] }\n", 200);
  EXPECT_EQ(slow.fault_cycle, kNever) << slow.fault;
}

TEST(Envelope, InsideItNothingTrips) {
  LODE_REQUIRE_PLUGINS("source.ramp");
  const Outcome r = run(ramp_pipeline("  ramp.out: { max_abs: [1.0], max_rate: [1.01] }\n"), 900);
  ASSERT_TRUE(r.loaded) << r.diagnostics;
  EXPECT_EQ(r.fault_cycle, kNever) << r.fault;
}

TEST(Envelope, AFallbackMayCoastOnlyMaxInvalidS) {
  // kawato_planar_swap at 5 kHz: a Hall channel reads NaN from t = 1 s for 2 s; kf trips and
  // kf_coast takes over in cycle 5000, then runs on prediction alone. glsdc.pose may be
  // invalid for 0.05 s: cycle 5250 is 50 ms after the first NaN (still allowed), cycle 5251
  // is 50.2 ms: the fault.
  LODE_REQUIRE_PLUGINS("io.sim", "estimator.glsdc", "estimator.kalman", "estimator.hybrid_h2hinf", "source.sine",
                       "controller.discrete_tf");
  const std::string base = read_file(LODE_SOURCE_DIR "/config/kawato_planar_swap.yaml");
  const std::string nan = replace(base, "    seed: 1\n",
                               "    seed: 1\n    inject_nan: { channel: a1, start_s: 1.0, duration_s: 2.0 }\n");
  const Outcome r = run(nan, 10000);
  ASSERT_TRUE(r.loaded) << r.diagnostics;
  EXPECT_EQ(r.fault_cycle, 5251u) << r.fault;
  EXPECT_NE(r.fault.find("envelope: glsdc.pose has been invalid (non-finite) for 50.2 ms, longer than its "
                         "max_invalid_s of 50 ms"),
            std::string::npos)
      << r.fault;
  // Negative control: a dropout shorter than the bound (40 ms) rides through on the fallback.
  const std::string short_nan = replace(base, "    seed: 1\n",
                                     "    seed: 1\n    inject_nan: { channel: a1, start_s: 1.0, duration_s: 0.04 }\n");
  const Outcome through = run(short_nan, 7500);
  EXPECT_EQ(through.fault_cycle, kNever) << through.fault;
  // Without the envelope the same NaN is never stopped (the stage ran away): the bound is
  // what faults it.
  const std::string unbounded = replace(nan, "  glsdc.pose: { max_invalid_s: 0.05 }", "");
  const Outcome runaway = run(unbounded, 7500);
  EXPECT_EQ(runaway.fault_cycle, kNever) << runaway.fault;
}

TEST(Envelope, ConfigurationErrorsAreLocated) {
  LODE_REQUIRE_PLUGINS("source.ramp");
  for (const auto& [entry, message] : std::vector<std::pair<std::string, std::string>>{
           {"  ramp.nope: { max_abs: [1.0] }\n", "no output 'ramp.nope'"},
           {"  ramp.out: { max_abs: [1.0, 2.0] }\n", "max_abs"},
           {"  ramp.out: { max_rate: [-1.0] }\n", "every max_rate must be > 0"},
           {"  ramp.out: { min: [1.0], max: [0.0] }\n", "min < max"},
           {"  ramp.out: {}\n", "must set min, max, max_abs, max_rate or max_invalid_s"},
           {"  ramp.out: { max_abs: [1.0], maxx: 3 }\n", "unknown parameter 'maxx'"},
       }) {
    const Outcome r = run(ramp_pipeline(entry), 1);
    EXPECT_FALSE(r.loaded) << entry;
    EXPECT_NE(r.diagnostics.find(message), std::string::npos) << entry << "\n" << r.diagnostics;
    EXPECT_NE(r.diagnostics.find("envelope.yaml:"), std::string::npos) << r.diagnostics;
  }
}

// Every shipped pipeline says where its stage may be. A simulated one runs its whole length
// inside its envelope (the bounds match the stage, not a tighter guess that trips on a good
// run), and a reference beyond the stage's travel, the typo a user makes, is stopped by it.
struct Shipped {
  const char* file;
  const char* step_from = nullptr;  ///< text of the first reference step
  const char* step_to = nullptr;    ///< the same step beyond the travel
};

class ShippedEnvelope : public ::testing::TestWithParam<Shipped> {};

TEST_P(ShippedEnvelope, TheNominalRunStaysInsideAndAReferenceBeyondTheTravelFaults) {
  LODE_REQUIRE_PLUGINS("io.sim");
  const Shipped& c = GetParam();
  const std::string text = read_config(c.file);
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(text, c.file, registry, diag);
  if (!p && diag.format().find("no plugin") != std::string::npos) GTEST_SKIP() << diag.format();
  ASSERT_TRUE(p) << diag.format();
  ASSERT_TRUE(p->default_duration_s()) << c.file << " has no duration_s";
  const auto cycles = static_cast<std::uint64_t>(std::llround(*p->default_duration_s() * p->rate_hz()));
  p.reset();

  const Outcome nominal = run(text, cycles);
  ASSERT_TRUE(nominal.loaded) << nominal.diagnostics;
  EXPECT_EQ(nominal.fault_cycle, kNever) << c.file << ": " << nominal.fault;

  if (c.step_from == nullptr) return;
  const Outcome typo = run(replace(text, c.step_from, c.step_to), cycles);
  ASSERT_TRUE(typo.loaded) << typo.diagnostics;
  EXPECT_NE(typo.fault_cycle, kNever) << c.file << ": a reference beyond the travel ran to the end";
  EXPECT_TRUE(typo.envelope) << typo.fault;
  std::printf("%-26s %llu cycles inside; reference beyond the travel: cycle %llu, %s\n", c.file,
              static_cast<unsigned long long>(cycles), static_cast<unsigned long long>(typo.fault_cycle),
              typo.fault.c_str());
}

INSTANTIATE_TEST_SUITE_P(
    Config, ShippedEnvelope,
    ::testing::Values(Shipped{"kawato_planar.yaml", "value: [100.0e-6, 0.0, 0.0]", "value: [0.2, 0.0, 0.0]"},
                      Shipped{"kawato_planar_swap.yaml"},
                      Shipped{"kawato_planar_true_field.yaml", "value: [100.0e-6, 0.0, 0.0]", "value: [0.2, 0.0, 0.0]"},
                      Shipped{"maglev6_hybrid.yaml", "value: [20.0e-6, 0, 0, 0, 0, 0]", "value: [0.2, 0, 0, 0, 0, 0]"},
                      Shipped{"npo_velocity.yaml", "value: [500.0e-9, 250.0e-9,", "value: [1.0e-3, 250.0e-9,"},
                      Shipped{"suspension_ukf.yaml", "value: [0.022, 0.0, 0.3320]", "value: [0.5, 0.0, 0.3320]"}, Shipped{"encoder_ekf.yaml"}),
    [](const auto& shipped) {
      std::string name = shipped.param.file;
      return name.substr(0, name.find('.'));
    });

TEST(Envelope, EveryShippedPipelineDeclaresOne) {
  // Including the hardware ones, which this test cannot run: the text must have the section.
  std::size_t seen = 0;
  for (const auto& entry : std::filesystem::directory_iterator(LODE_SOURCE_DIR "/config")) {
    if (entry.path().extension() != ".yaml") continue;
    ++seen;
    const std::string text = read_file(entry.path().string());
    EXPECT_NE(text.find("\nenvelope:"), std::string::npos) << entry.path() << " declares no envelope";
  }
  EXPECT_GE(seen, 9u);
}

}  // namespace
