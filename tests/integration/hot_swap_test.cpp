// hot swap, shadows and the health monitor on Kawato's (2005) planar stage at 5 kHz
// (config/kawato_planar_swap.yaml), with the test thread playing the RT thread so every
// cycle is reproducible: before_cycle hooks, run_cycle, after_cycle hooks, as the scheduler.
//
// The jump bound. Both filters run per axis on x = [p, v, a] with the same model
// (Phi, H = [1 0 0]) and output the one-step prediction H Phi x+_k. A swap at cycle k hands the
// incumbent's prior x-_k over exactly, so the newcomer and the incumbent see the same
// innovation nu_k = y_k - H x-_k, and the outputs differ only through their gains:
//
//     jump_k = H Phi (K_new - K_old) nu_k                                       (1)
//
// With consistent innovations, |nu_k| < 6 sqrt(S) except with probability 2e-9, so
//
//     |jump| <= B = |H Phi (K_new - K_old)| 6 sqrt(S)                          (2)
//
// where for Kalman -> hybrid K_old is the Kalman gain of the current prior (between the
// steady-state gain and the gain of the hybrid's covariance it was warm-started from) and
// K_new the hybrid's blended steady gain (Silva-Rivas & Kim 2013, eq. 25), and for
// hybrid -> Kalman K_old is the blended gain and K_new = P_h H' / (H P_h H' + r) from the
// hybrid's exported steady prior covariance P_h. The test checks (1) to rounding at every swap (this fails if the state
// is not handed over exactly) and (2) at every swap, and reports the ratios.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <chrono>
#include <thread>
#include <cstdio>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "lode/sdk/estimator_state.hpp"
#include "lode/event_log.hpp"
#include "lode/hot_swap.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "config_text.hpp"
#include "swap_rig.hpp"

namespace {

using lode::test::read_config;
using lode::test::read_file;
using lode::test::replace;

const char* kHybridParams =
    "{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], hinf_theta: 1.0e8, d: 0.5, output: predicted}";
const char* kKalmanParams =
    "{motion: constant_acceleration, q: [1.0e2, 1.0e2, 1.0e5], p0: 1.0e-8, r: [2.2e-10, 2.2e-10, 9.6e-9], "
    "output: predicted}";
constexpr std::array<double, 3> kR{2.2e-10, 2.2e-10, 9.6e-9};

/// The swap rig, and swaps as the runner does them, with the allocations of the cycles in
/// between counted.
struct Rig : lode::test::SwapRig {
  explicit Rig(const std::string& yaml, std::vector<std::string> extra_search = {})
      : SwapRig(yaml, "kawato_planar_swap.yaml (test)", std::move(extra_search)) {}
  /// `at_boundary` runs at the end of every cycle (before the after_cycle hooks, where the
  /// exchange happens) until the swap is done.
  lode::SwapReport swap(const lode::SwapRequest& request, const std::function<void()>& at_boundary = {}) {
    auto prepared = swapper->prepare(request);
    if (!prepared) {
      lode::SwapReport r;
      r.message = prepared.error();
      return r;
    }
    swapper->post(**prepared);
    const auto before = lode::testing::allocation_count();
    while (!swapper->done()) last = step(at_boundary);
    rt_allocations += lode::testing::allocation_count() - before;
    return swapper->finish(std::move(*prepared));
  }

  lode::Pipeline::CycleResult last;
  std::uint64_t rt_allocations = 0;
};

const lode::Json& at(const lode::Json& j, const std::string& key) {
  const lode::Json* v = j.find(key);
  EXPECT_NE(v, nullptr) << "describe() has no '" << key << "'";
  static const lode::Json null;
  return v ? *v : null;
}

std::array<double, 3> row(const lode::Json& a) {
  std::array<double, 3> out{};
  for (std::size_t i = 0; i < 3 && i < a.elements().size(); ++i) out[i] = a.elements()[i].as_number();
  return out;
}

/// H Phi k = k0 + T k1 + T^2/2 k2 (H = [1 0 0], Phi of constant acceleration).
double h_phi(const std::array<double, 3>& k, double T) { return k[0] + T * k[1] + 0.5 * T * T * k[2]; }

/// Kalman gain of a 3x3 prior (row-major, one axis) with measurement variance r.
std::array<double, 3> kalman_gain(const double* p, double r) {
  const double s = p[0] + r;
  return {p[0] / s, p[3] / s, p[6] / s};
}

TEST(HotSwap, ThousandSwapsKalmanHybridAt5kHzKeepTheLoopAndBoundTheJump) {
  LODE_REQUIRE_ALLOCATION_COUNTING();
  Rig rig(read_config("kawato_planar_swap.yaml"));
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  ASSERT_TRUE(rig.activated);
  const double T = 1.0 / rig.pipeline->rate_hz();
  ASSERT_EQ(rig.pipeline->rate_hz(), 5000.0);

  // Gains for the a-priori bound (2), from the hybrid shadow (same parameters as the swaps)
  // and the Kalman steady state.
  const lode::Json d = rig.pipeline->describe();
  const lode::Json& hybrid_axes = at(at(at(at(d, "blocks"), "kf_hybrid"), "derived"), "axes");
  const lode::Json& kalman_axes = at(at(at(at(d, "blocks"), "kf"), "derived"), "axes");
  ASSERT_EQ(hybrid_axes.elements().size(), 3u);
  ASSERT_EQ(kalman_axes.elements().size(), 3u);
  std::array<double, 3> bound{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto k_h = row(at(hybrid_axes.elements()[i], "blended_gain"));
    const lode::Json& ss = at(kalman_axes.elements()[i], "steady_state");
    const auto k_kf = row(at(ss, "gain"));
    std::vector<double> p_kf, p_h;
    for (const auto& r : at(ss, "prior_covariance").elements())
      for (const auto& v : r.elements()) p_kf.push_back(v.as_number());
    for (const auto& r : at(hybrid_axes.elements()[i], "steady_prior_covariance").elements())
      for (const auto& v : r.elements()) p_h.push_back(v.as_number());
    ASSERT_EQ(p_kf.size(), 9u);
    ASSERT_EQ(p_h.size(), 9u);
    const auto k_of_ph = kalman_gain(p_h.data(), kR[i]);
    auto diff = [&](const std::array<double, 3>& a, const std::array<double, 3>& b) {
      return std::abs(h_phi({a[0] - b[0], a[1] - b[1], a[2] - b[2]}, T));
    };
    const double c = std::max({diff(k_h, k_kf), diff(k_h, k_of_ph)});
    const double sigma = std::sqrt(std::max(p_kf[0], p_h[0]) + kR[i]);
    bound[i] = c * 6.0 * sigma;
    std::printf("axis %zu: K_kf %.4g %.4g %.4g  K_h %.4g %.4g %.4g  K(P_h) %.4g  |H Phi dK| <= %.4g  "
                "sqrt(S) %.4g  bound %.4g\n",
                i, k_kf[0], k_kf[1], k_kf[2], k_h[0], k_h[1], k_h[2], k_of_ph[0], c, sigma, bound[i]);
  }

  // Settle (the sine starts at 0.5 s), then 1000 swaps, 100 cycles (20 ms) apart.
  for (int i = 0; i < 3000; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
  std::array<double, 3> worst_ratio{}, worst_identity{};
  std::vector<double> costs, prepare_ms;
  double max_track_error = 0.0;
  for (int s = 0; s < 1000; ++s) {
    const bool to_hybrid = s % 2 == 0;
    // The incumbent's prior at the exchange boundary gives K_old.
    std::vector<double> x(9), P(81);
    lode::SwapRequest req;
    req.block = "kf";
    req.plugin = to_hybrid ? "estimator.hybrid_h2hinf" : "estimator.kalman";
    req.params = to_hybrid ? kHybridParams : kKalmanParams;
    lode::Block* incumbent = rig.pipeline->block("kf");
    const lode::SwapReport r = rig.swap(req, [&] {
      if (rig.pipeline->block("kf") == incumbent)
        dynamic_cast<lode::EstimatorState&>(*incumbent).export_state(x.data(), P.data());
    });
    ASSERT_TRUE(r.ok) << r.message;
    ASSERT_EQ(r.jump.size(), 3u) << r.message;
    ASSERT_EQ(r.mapped, 9u) << r.message;
    const auto nu = rig.value("kf.innovation");
    for (std::size_t i = 0; i < 3; ++i) {
      // (1): jump = H Phi (K_new - K_old) nu, K from the exported priors and the describe()d gains.
      std::array<double, 3> k_old{}, k_new{};
      const auto& axes = to_hybrid ? hybrid_axes : kalman_axes;
      (void)axes;
      const auto k_h = row(at(hybrid_axes.elements()[i], "blended_gain"));
      double p_axis[9];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) p_axis[a * 3 + b] = P[(3 * i + a) * 9 + 3 * i + b];
      if (to_hybrid) {
        k_old = kalman_gain(p_axis, kR[i]);
        k_new = k_h;
      } else {
        k_old = k_h;
        k_new = kalman_gain(p_axis, kR[i]);  // P is the hybrid's exported steady prior
      }
      const double expected = h_phi({k_new[0] - k_old[0], k_new[1] - k_old[1], k_new[2] - k_old[2]}, T) * nu[i];
      const double identity = std::abs(r.jump[i] - expected) / (std::abs(expected) + 1e-18);
      worst_identity[i] = std::max(worst_identity[i], identity);
      EXPECT_LT(std::abs(r.jump[i] - expected), 1e-6 * std::abs(expected) + 1e-15)
          << "swap " << s << " axis " << i << ": jump " << r.jump[i] << " vs H Phi dK nu " << expected;
      worst_ratio[i] = std::max(worst_ratio[i], std::abs(r.jump[i]) / bound[i]);
      EXPECT_LE(std::abs(r.jump[i]), bound[i]) << "swap " << s << " axis " << i;
    }
    costs.push_back(static_cast<double>(r.rt_cost_ns));
    prepare_ms.push_back(r.prepare_ns * 1e-6);
    for (int c = 0; c < 100; ++c) {
      ASSERT_EQ(rig.step().status, lode::StepStatus::ok) << "cycle " << rig.cycle;
      const auto truth = rig.value("stage.truth");
      const auto ref = rig.value("ref.out");
      max_track_error = std::max(max_track_error, std::abs(truth[0] - ref[0]));
    }
  }
  std::sort(costs.begin(), costs.end());
  std::sort(prepare_ms.begin(), prepare_ms.end());
  std::printf("1000 swaps at 5 kHz: max |jump|/bound x %.3g y %.3g theta %.3g; identity (1) worst rel. error %.2g\n",
              worst_ratio[0], worst_ratio[1], worst_ratio[2],
              std::max({worst_identity[0], worst_identity[1], worst_identity[2]}));
  std::printf("RT cost of a swap: median %.0f ns, p99 %.0f ns, max %.0f ns; off-RT preparation median %.2f ms, max %.2f ms\n",
              costs[costs.size() / 2], costs[costs.size() * 99 / 100], costs.back(), prepare_ms[prepare_ms.size() / 2],
              prepare_ms.back());
  std::printf("tracking: max |x - x_ref| over %llu cycles with swaps: %.3g m\n",
              static_cast<unsigned long long>(rig.cycle), max_track_error);
  // The loop stays stable: the 50 um sine is tracked within a few um all along.
  EXPECT_LT(max_track_error, 20e-6);
  // RT cost: measured above; asserted only loosely here (shared, noisy machine; the figure is
  // the benchmark's, tests/bench/hot_swap_bench.cpp).
  EXPECT_LT(costs[costs.size() / 2], 20000.0);
  EXPECT_EQ(rig.rt_allocations, 0u);
}

TEST(HotSwap, ColdStartWouldJumpFarMoreThanAWarmStart) {
  Rig rig(read_config("kawato_planar_swap.yaml"));
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  for (int i = 0; i < 4000; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
  lode::SwapRequest req;
  req.block = "kf";
  req.plugin = "estimator.hybrid_h2hinf";
  req.params = kHybridParams;
  const auto warm = rig.swap(req);
  ASSERT_TRUE(warm.ok) << warm.message;
  for (int i = 0; i < 100; ++i) rig.step();
  req.plugin = "estimator.kalman";
  req.params = kKalmanParams;
  req.warm_start = false;
  const auto cold = rig.swap(req);
  ASSERT_TRUE(cold.ok) << cold.message;
  ASSERT_EQ(cold.jump.size(), 3u);
  std::printf("warm jump x %.3g m; cold (no state handover) jump x %.3g m, v would start at 0\n", warm.jump[0],
              cold.jump[0]);
  EXPECT_GT(std::abs(cold.jump[0]), 10 * std::abs(warm.jump[0]));
}

TEST(HotSwap, ASwapPendingWhenThePipelineStopsIsWithdrawnWithTheReason) {
  Rig rig(read_config("kawato_planar_swap.yaml"));
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  for (int i = 0; i < 100; ++i) rig.step();
  lode::SwapRequest req;
  req.block = "kf";
  req.plugin = "estimator.hybrid_h2hinf";
  req.params = kHybridParams;
  lode::SwapReport report;
  // No cycle runs: the request stays posted until the "RT thread" is declared stopped.
  std::thread caller([&] { report = rig.swapper->swap(req); });
  // Stop once the request is posted: stopping while it is still being prepared (loading the
  // plugin can take longer than any fixed wait on a loaded or instrumented build) would test
  // the other path, a swap into a pipeline that is not running.
  for (int i = 0; i < 20000 && !rig.swapper->posted(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const bool was_posted = rig.swapper->posted();
  rig.swapper->set_running(false);
  caller.join();
  ASSERT_TRUE(was_posted) << "the swap was never posted within 20 s";
  EXPECT_FALSE(report.ok);
  EXPECT_NE(report.message.find("the pipeline stopped before the exchange"), std::string::npos) << report.message;
  EXPECT_EQ(rig.pipeline->plugin_of("kf"), "estimator.kalman");
}

TEST(HotSwap, RefusedPluginsLeaveTheIncumbentRunning) {
  Rig rig(read_config("kawato_planar_swap.yaml"), {LODE_BAD_PLUGIN_DIR});
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  for (int i = 0; i < 200; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
  lode::Block* before = rig.pipeline->block("kf");
  struct Case {
    std::string plugin, params, expect;
  };
  const std::vector<Case> cases = {
      {"estimator.not_there", "{}", "cannot be used"},
      {"test.no_symbol", "{}", "cannot be used"},                       // fails to load (dlopen/dlsym)
      {"test.wrong_abi", "{}", "cannot be used"},                       // built for another ABI
      {"test.throws_in_configure", "{anything: 1}", "configure() threw"},
      {"sensor.halbach_hall", "{}", "not a block"},                     // a model
      {"io.sim", "{}", "an io board"},                                  // wrong kind
      {"estimator.glsdc", "{model: hall_fit}", "size mismatch"},        // kf's wiring does not fit it
      {"filter.biquad", "{type: lowpass, f_hz: 100, q: 0.7071, inputs: {in: glsdc.pose}}",
       "(filter.biquad is of kind filter; kf runs estimator.kalman, of kind estimator): it has no output"},  // configures, cannot stand in
      {"controller.pid", "{}",  // another kind, refusing its parameters: the kind is said first
       "controller.pid refused its configuration (controller.pid is of kind controller; kf runs estimator.kalman, of kind estimator): "},
      {"estimator.hybrid_h2hinf", "{q: 1, r: 1, hinf_theta: 0, d: 2}", "d"},  // refuses its parameters
      {"estimator.kalman", "{q: [1, 2]", "not valid YAML"},
      // Its wiring is read by the loader's own rules: a map or a half reference is refused
      // with the loader's messages, not thrown or looked up as a block named ''.
      {"estimator.kalman", "{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], inputs: {measurement: {a: 1}}}",
       "inputs.measurement: expected `block.port`"},
      {"estimator.kalman", "{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], inputs: {measurement: .pose}}",
       "'.pose' is not a `block.port` reference"},
  };
  for (const auto& c : cases) {
    lode::SwapRequest req;
    req.block = "kf";
    req.plugin = c.plugin;
    req.params = c.params;
    const auto r = rig.swapper->swap(req);
    EXPECT_FALSE(r.ok) << c.plugin;
    EXPECT_NE(r.message.find(c.expect), std::string::npos) << c.plugin << ": " << r.message;
    EXPECT_NE(r.message.find("unchanged"), std::string::npos) << r.message;
    EXPECT_EQ(rig.pipeline->block("kf"), before) << c.plugin;
    const auto pose_before = rig.value("kf.pose");
    for (int i = 0; i < 20; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
    EXPECT_NE(rig.value("kf.pose"), pose_before) << "the incumbent must keep running after " << c.plugin;
  }
  std::size_t refused = 0;
  for (const auto& e : rig.events.snapshot()) refused += e.kind == "command_failed";
  // Refusals beyond 10 a second are counted, not posted (a flood must not fill the log).
  EXPECT_EQ(refused + rig.events.suppressed(), cases.size());
  EXPECT_EQ(refused, std::min<std::size_t>(cases.size(), 10));
  // io blocks are never swappable.
  lode::SwapRequest io;
  io.block = "stage";
  io.plugin = "io.sim";
  const auto r = rig.swapper->swap(io);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("is an io block"), std::string::npos) << r.message;
  lode::SwapRequest none;
  none.block = "nothing";
  none.plugin = "estimator.kalman";
  const auto r2 = rig.swapper->swap(none);
  EXPECT_FALSE(r2.ok);
  EXPECT_NE(r2.message.find("no swappable block 'nothing' (swappable: "), std::string::npos) << r2.message;
}

TEST(HotSwap, PromoteExchangesPrimaryAndShadowAndBack) {
  Rig rig(read_config("kawato_planar_swap.yaml"));
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  for (int i = 0; i < 3000; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
  EXPECT_EQ(rig.pipeline->plugin_of("kf"), "estimator.kalman");
  EXPECT_EQ(rig.pipeline->plugin_of("kf_hybrid"), "estimator.hybrid_h2hinf");
  // Before: the shadow's disagreement is its pose minus kf.pose.
  const auto shadow_pose = rig.value("kf_hybrid.pose");
  const auto primary_pose = rig.value("kf.pose");
  const auto disagreement = rig.value("kf_hybrid.disagreement");
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(disagreement[i], shadow_pose[i] - primary_pose[i]);
  auto prepared_swapper = rig.swapper.get();
  // promote() waits for a boundary: drive cycles from another thread's point of view by
  // using the not-running path (applied at once, same code).
  prepared_swapper->set_running(false);
  const auto r = rig.swapper->promote("kf_hybrid");
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(rig.pipeline->plugin_of("kf"), "estimator.hybrid_h2hinf");
  EXPECT_EQ(rig.pipeline->plugin_of("kf_hybrid"), "estimator.kalman");
  for (int i = 0; i < 500; ++i) ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
  const auto r2 = rig.swapper->promote("kf_hybrid");
  ASSERT_TRUE(r2.ok) << r2.message;
  EXPECT_EQ(rig.pipeline->plugin_of("kf"), "estimator.kalman");
  const auto bad = rig.swapper->promote("glsdc");
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.message.find("not a shadow"), std::string::npos) << bad.message;
}

TEST(HotSwap, ShadowsPublishNisAndMayBeDecimated) {
  std::string yaml = read_config("kawato_planar_swap.yaml");
  // At 1 kHz the blend d = 0.5 is unstable on theta_z (the loader says so); d = 0.9 is not.
  yaml = replace(yaml, "    shadow_of: kf\n    plugin: estimator.hybrid_h2hinf\n",
                 "    shadow_of: kf\n    shadow_decimation: 5\n    plugin: estimator.hybrid_h2hinf\n");
  yaml = replace(yaml, "    d: 0.5\n", "    d: 0.9\n");
  Rig rig(yaml);
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  // The NIS the pipeline publishes for kf_coast must be nu' S^-1 nu with nu = y_k - H x-_k
  // (H x-_k is kf_coast's predicted output of the cycle before) and S = H P- H' + r at steady
  // state (kf_coast has kf's parameters, so describe(kf) gives P-).
  const lode::Json d = rig.pipeline->describe();
  const lode::Json& kalman_axes = at(at(at(at(d, "blocks"), "kf"), "derived"), "axes");
  ASSERT_EQ(kalman_axes.elements().size(), 3u);
  std::array<double, 3> s_steady{};
  for (std::size_t i = 0; i < 3; ++i) {
    const lode::Json& prior = at(at(kalman_axes.elements()[i], "steady_state"), "prior_covariance");
    s_steady[i] = prior.elements()[0].elements()[0].as_number() + kR[i];
  }
  double coast_nis = 0.0, worst_relative = 0.0;
  std::array<double, 3> nu_squared{};
  int n = 0;
  std::vector<double> hybrid_pose_changes;
  auto previous = rig.value("kf_hybrid.pose");
  auto coast_previous = rig.value("kf_coast.pose");
  for (int i = 0; i < 5000; ++i) {
    ASSERT_EQ(rig.step().status, lode::StepStatus::ok);
    if (i >= 1000) {
      const auto y = rig.value("glsdc.pose");
      double expected = 0.0;
      for (std::size_t a = 0; a < 3; ++a) {
        const double nu = y[a] - coast_previous[a];
        nu_squared[a] += nu * nu;
        expected += nu * nu / s_steady[a];
      }
      const double published = rig.value("kf_coast.nis")[0];
      worst_relative = std::max(worst_relative, std::abs(published - expected) / expected);
      coast_nis += published;
      ++n;
    }
    coast_previous = rig.value("kf_coast.pose");
    const auto now = rig.value("kf_hybrid.pose");
    hybrid_pose_changes.push_back(now != previous ? 1.0 : 0.0);
    previous = now;
  }
  const double mean_nis = coast_nis / n;
  std::printf("kf_coast mean NIS over %d cycles: %.4f (3 channels); published vs nu'S^-1 nu: worst rel. err %.2e\n",
              n, mean_nis, worst_relative);
  for (std::size_t a = 0; a < 3; ++a)
    std::printf("  axis %zu: mean nu^2 / S = %.4f (S = %.4g)\n", a, nu_squared[a] / n / s_steady[a], s_steady[a]);
  EXPECT_LT(worst_relative, 1e-6);
  // The configured r is the thesis's hardware fit; the simulated GLSDC poses are far less noisy,
  // so the NIS sits well below 3 (an honest finding, not a defect of the statistic).
  EXPECT_GT(mean_nis, 0.0);
  EXPECT_TRUE(std::isfinite(mean_nis));
  // The decimated shadow moves only every 5th cycle.
  int moved = 0;
  for (double c : hybrid_pose_changes) moved += c > 0;
  EXPECT_NEAR(moved, 1000, 5);
  EXPECT_NE(rig.pipeline->describe().dump(-1).find("\"shadow_decimation\": 5"), std::string::npos);
}

/// io.sim turns one Hall channel NaN for 5 ms at 1 s (fault injection).
std::string with_nan_injection(std::string yaml) {
  return replace(yaml, "    seed: 1\n    inputs: { command: ctrl.out }\n",
                 "    seed: 1\n    inject_nan: { channel: a1, start_s: 1.0, duration_s: 0.005 }\n"
                 "    inputs: { command: ctrl.out }\n");
}

TEST(HealthMonitor, NanMeasurementTripsAndTheFallbackTakesOverInTheSameCycle) {
  Rig rig(with_nan_injection(read_config("kawato_planar_swap.yaml")));
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  std::uint64_t first_nan = 0;
  bool seen_nan = false;
  for (int i = 0; i < 7500; ++i) {
    const auto r = rig.step();
    ASSERT_EQ(r.status, lode::StepStatus::ok) << "cycle " << rig.cycle - 1;
    const auto signals = rig.value("stage.signals");
    if (!seen_nan && std::isnan(signals[0])) {
      seen_nan = true;
      first_nan = rig.cycle - 1;
      // The cycle in which the measurement turned NaN: the controller already got a finite
      // estimate from the fallback.
      for (double v : rig.value("kf.pose")) EXPECT_TRUE(std::isfinite(v));
      for (double v : rig.value("ctrl.out")) EXPECT_TRUE(std::isfinite(v));
    }
    for (double v : rig.value("kf.pose")) ASSERT_TRUE(std::isfinite(v)) << "cycle " << rig.cycle - 1;
  }
  ASSERT_TRUE(seen_nan) << "io.sim inject_nan did not inject";
  EXPECT_EQ(first_nan, 5000u);
  EXPECT_EQ(rig.swapper->poll_events(), 1u);
  const auto events = rig.events.snapshot();
  ASSERT_FALSE(events.empty());
  const auto& e = events.back();
  EXPECT_EQ(e.kind, "health");
  EXPECT_EQ(e.cycle, first_nan);
  EXPECT_NE(e.text.find("fallback kf_coast took over in the same cycle"), std::string::npos) << e.text;
  EXPECT_NE(e.text.find("non-finite"), std::string::npos) << e.text;
  std::printf("event: %s\n", e.text.c_str());
  // The stage kept tracking through the 5 ms dropout and after.
  const auto truth = rig.value("stage.truth");
  const auto ref = rig.value("ref.out");
  EXPECT_LT(std::abs(truth[0] - ref[0]), 20e-6);
}

TEST(HealthMonitor, WithoutAFallbackATripDrivesTheOutputsSafe) {
  std::string yaml = with_nan_injection(read_config("kawato_planar_swap.yaml"));
  yaml = replace(yaml, "    fallback: kf_coast ", "    # no fallback ");
  Rig rig(yaml);
  ASSERT_TRUE(rig.pipeline) << rig.diagnostics.format();
  lode::Pipeline::CycleResult r;
  while (rig.cycle < 7500) {
    r = rig.step();
    if (r.status != lode::StepStatus::ok) break;
  }
  ASSERT_EQ(r.status, lode::StepStatus::fault);
  EXPECT_EQ(rig.cycle - 1, 5000u);
  ASSERT_NE(r.reason, nullptr);
  std::printf("trip without fallback at cycle %llu: %s\n", static_cast<unsigned long long>(rig.cycle - 1), r.reason);
  EXPECT_EQ(rig.swapper->poll_events(), 1u);
  EXPECT_NE(rig.events.snapshot().back().text.find("outputs driven safe"), std::string::npos);
}

TEST(HealthMonitor, ConfigurationErrorsAreLocated) {
  const std::string base = read_config("kawato_planar_swap.yaml");
  struct Case {
    std::string from, to, expect;
  };
  const std::vector<Case> cases = {
      {"    fallback: kf_coast ", "    fallback: glsdc ", "'glsdc' is not a shadow of 'kf'"},
      {"health:\n  kf:\n", "health:\n  stage:\n", "io block"},
      {"    shadow_of: kf\n    plugin: estimator.hybrid_h2hinf", "    shadow_of: nothing\n    plugin: estimator.hybrid_h2hinf",
       "no block named 'nothing'"},
      {"inputs: { measurement: kf.pose, reference: ref.out }", "inputs: { measurement: kf_hybrid.pose, reference: ref.out }",
       "is a shadow of 'kf'"},
      {"    nis_window: 500 ", "    nis_window: -1 ", "nis_window"},
  };
  for (const auto& c : cases) {
    lode::PluginRegistry registry;
    lode::Diagnostics diag;
    auto p = lode::Pipeline::load_text(replace(base, c.from, c.to), "swap.yaml", registry, diag);
    EXPECT_FALSE(p) << c.expect;
    EXPECT_NE(diag.format().find(c.expect), std::string::npos) << diag.format();
    EXPECT_NE(diag.format().find("swap.yaml:"), std::string::npos) << diag.format();
  }
}

}  // namespace

namespace {

// A shadow stands in for its primary by the same rule a hot swap's newcomer does: every
// output, same size, compatible units. "m/s^2" and "m/s2" are one unit; the loader once
// compared spellings and refused such a shadow that a swap would have accepted.
TEST(StandIn, ShadowAndSwapUseOneRuleForUnits) {
  const std::string yaml = R"(pipeline: stand_in
rate_hz: 1000
blocks:
  a: {plugin: source.step, names: [x], units: [m/s^2], steps: [{time_s: 0.01, value: [1.0]}]}
  b: {plugin: source.step, names: [x], units: [m/s2], steps: [{time_s: 0.01, value: [1.0]}]}
  c: {plugin: source.step, names: [x], units: [rad], steps: [{time_s: 0.01, value: [1.0]}]}
  primary: {plugin: filter.biquad, type: lowpass, f_hz: 100, q: 0.7071, inputs: {in: a.out}}
  same_unit: {plugin: filter.biquad, shadow_of: primary, type: lowpass, f_hz: 50, q: 0.7071, inputs: {in: b.out}}
)";
  lode::PluginRegistry registry;
  lode::Diagnostics diagnostics;
  auto p = lode::Pipeline::load_text(yaml, "stand_in.yaml", registry, diagnostics);
  EXPECT_TRUE(p) << diagnostics.format();
  // Another unit is still refused, with the rule's words.
  lode::Diagnostics other;
  auto q = lode::Pipeline::load_text(yaml + "  other_unit: {plugin: filter.biquad, shadow_of: primary, type: lowpass, "
                                            "f_hz: 50, q: 0.7071, inputs: {in: c.out}}\n",
                                     "stand_in.yaml", registry, other);
  EXPECT_FALSE(q);
  EXPECT_NE(other.format().find("cannot stand in for 'primary'"), std::string::npos) << other.format();
  EXPECT_NE(other.format().find("in 'rad'"), std::string::npos) << other.format();
}

}  // namespace
