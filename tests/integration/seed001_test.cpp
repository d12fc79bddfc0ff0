// Zimmerman, Oshman & Brandes (2006): the paper's simulation through the real
// loader and scheduler. config/encoder_ekf.yaml is loaded, its trajectory / sampling rate /
// sigma_m^2 are changed per case, and the run's errors are compared with Tables 2, 3 and 4,
// the Fig. 6 steady state and these acceptance criteria (set here from the paper's numbers):
//   1. steady-state sqrt(P) (a posteriori) within 5 % of 1.7 nm / 2.6 um/s
//   2. EKF position 1 sigma within 10 % of each Table 2 entry
//   3. EKF velocity 1 sigma within 20 % of each Table 3 entry
//   4. baseline within 5 % of 5.15 nm / 145 um/s
//   5. ratios baseline/EKF >= 3 (position) and >= 60 (velocity) in every column
//   6. Table 4 rows: position within 15 %, velocity within 15 % (30 % on row 1)
//   7. consistency: EKF position error sigma within 15 % of sqrt(P11)
// Every run: seed 1, 2 s (1 s at 100 kHz), statistics after the first 0.2 s (the paper gives
// neither duration nor start-up window).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <ostream>
#include <string>
#include <vector>

#include "config_text.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "tapped_run.hpp"

namespace {

using lode::test::read_file;

const std::string kConfig = LODE_SOURCE_DIR "/config/encoder_ekf.yaml";
constexpr double kSettleS = 0.2;  // discard the first 0.2 s (start-up; the paper calls it "fast")

/// One simulated case: the trajectory, the sampling rate and the filter's sigma_m^2.
struct Case {
  const char* name;
  double amplitude_m = 0.0;
  double frequency_hz = 0.0;
  double velocity_m_s = 0.0;
  double rate_hz = 20000.0;
  double acceleration_variance = 1e-5;
  double duration_s = 2.0;
  std::uint64_t seed = 1;
};

/// 1 sigma (standard deviation) of the errors after kSettleS, and the filter's own sigma.
struct Result {
  double ekf_position_m = 0.0;
  double ekf_velocity_m_s = 0.0;
  double baseline_position_m = 0.0;
  double baseline_velocity_m_s = 0.0;
  double ekf_predicted_position_m = 0.0;  // sqrt P11(k|k) at the end of the run
  double ekf_predicted_velocity_m_s = 0.0;
  double ekf_max_position_error_m = 0.0;  // after kSettleS
  std::size_t samples = 0;
  bool faulted = false;
  std::string fault;
  lode::Json describe;
};

class ErrorStats {
 public:
  void add(double e) {
    ++n_;
    const double d = e - mean_;
    mean_ += d / static_cast<double>(n_);
    m2_ += d * (e - mean_);
    max_abs_ = std::max(max_abs_, std::abs(e));
  }
  [[nodiscard]] double std() const { return n_ > 1 ? std::sqrt(m2_ / static_cast<double>(n_ - 1)) : NAN; }
  [[nodiscard]] double max_abs() const { return max_abs_; }

 private:
  std::size_t n_ = 0;
  double mean_ = 0.0;
  double m2_ = 0.0;
  double max_abs_ = 0.0;
};

std::string case_yaml(const Case& c) {
  YAML::Node root = YAML::Load(read_file(kConfig));
  root["rate_hz"] = c.rate_hz;
  root["models"]["axis"]["amplitude_m"] = c.amplitude_m;
  root["models"]["axis"]["frequency_hz"] = c.frequency_hz;
  root["models"]["axis"]["velocity_m_s"] = c.velocity_m_s;
  root["blocks"]["ekf"]["acceleration_variance_m2_s4"] = c.acceleration_variance;
  root["blocks"]["stage"]["seed"] = c.seed;
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << root;
  return out.c_str();
}

Result run(const Case& c) {
  Result r;
  lode::PluginRegistry registry;
  lode::Diagnostics diag;
  auto p = lode::Pipeline::load_text(case_yaml(c), std::string("seed001_") + c.name + ".yaml", registry, diag);
  EXPECT_TRUE(p) << diag.format();
  if (!p) return r;
  r.describe = p->describe();
  EXPECT_TRUE(p->activate());
  const lode::test::TappedRun run =
      lode::test::run_tapped(*p, {"stage.truth", "ekf.estimate", "arctan.estimate", "ekf.std"},
                             static_cast<std::uint64_t>(std::llround(c.duration_s * c.rate_hz)), 1 << 14,
                             /*time_ops=*/false);
  r.faulted = run.faulted;
  r.fault = run.fault;
  EXPECT_EQ(run.dropped, 0u);

  ErrorStats ekf_x, ekf_v, base_x, base_v;
  for (std::size_t k = 0; k < run.size(); ++k) {
    const double t = run.time_s(k);
    const double* tr = run.values(k, 0);
    const double* ek = run.values(k, 1);
    const double* ba = run.values(k, 2);
    const double* sd = run.values(k, 3);
    r.ekf_predicted_position_m = sd[0];
    r.ekf_predicted_velocity_m_s = sd[1];
    if (t < kSettleS) continue;
    ekf_x.add(ek[0] - tr[0]);
    ekf_v.add(ek[1] - tr[1]);
    base_x.add(ba[0] - tr[0]);
    base_v.add(ba[1] - tr[1]);
    ++r.samples;
  }
  r.ekf_position_m = ekf_x.std();
  r.ekf_velocity_m_s = ekf_v.std();
  r.baseline_position_m = base_x.std();
  r.baseline_velocity_m_s = base_v.std();
  r.ekf_max_position_error_m = ekf_x.max_abs();
  p->deactivate();
  return r;
}

const lode::Json& at(const lode::Json& j, const std::string& key) {
  const lode::Json* v = j.find(key);
  if (!v) throw std::runtime_error("describe() has no '" + key + "'");
  return *v;
}

/// The EKF block's describe() inside the pipeline's.
const lode::Json& ekf_describe(const lode::Json& pipeline) {
  return at(at(at(pipeline, "blocks"), "ekf"), "derived");
}

double relative(double measured, double printed) { return (measured - printed) / printed; }

// --- Tables 2 and 3: the six simulated inputs -------------------------------------------

struct Column {
  Case c;
  double paper_base_x_nm, paper_ekf_x_nm, paper_base_v_um_s, paper_ekf_v_um_s;
};

const Column kColumns[] = {
    {{"sine_5hz_1um", 1e-6, 5.0}, 5.17, 1.57, 146.2, 1.77},
    {{"sine_2hz_1um", 1e-6, 2.0}, 5.15, 1.54, 145.4, 1.69},
    {{"sine_10hz_1um", 1e-6, 10.0}, 5.15, 1.67, 144.9, 2.29},
    {{"sine_5hz_2um", 2e-6, 5.0}, 5.16, 1.54, 145.1, 1.84},
    {{"sine_5hz_0p5um", 0.5e-6, 5.0}, 5.15, 1.56, 145.4, 1.72},
    {{"ramp_2mm_s", 0.0, 0.0, 2e-3}, 5.13, 1.53, 144.5, 1.69},
};

/// GoogleTest prints the parameter in test listings (and so in ctest names): its name.
void PrintTo(const Column& column, std::ostream* os) { *os << column.c.name; }

class Tables23 : public ::testing::TestWithParam<Column> {};

TEST_P(Tables23, EkfAndBaselineMatchThePaper) {
  const Column& col = GetParam();
  const Result r = run(col.c);
  ASSERT_FALSE(r.faulted) << r.fault;
  ASSERT_GT(r.samples, 35000u);
  const double ekf_x_nm = r.ekf_position_m * 1e9, ekf_v_um = r.ekf_velocity_m_s * 1e6;
  const double base_x_nm = r.baseline_position_m * 1e9, base_v_um = r.baseline_velocity_m_s * 1e6;
  const double sqrt_p11_nm = r.ekf_predicted_position_m * 1e9;
  std::printf("%-15s  position nm: arctan %.3f (paper %.2f)  EKF %.3f (paper %.2f)  ratio %.2f | "
              "velocity um/s: arctan %.1f (paper %.1f)  EKF %.3f (paper %.2f)  ratio %.1f | sqrt(P11) %.3f nm\n",
              col.c.name, base_x_nm, col.paper_base_x_nm, ekf_x_nm, col.paper_ekf_x_nm, base_x_nm / ekf_x_nm,
              base_v_um, col.paper_base_v_um_s, ekf_v_um, col.paper_ekf_v_um_s, base_v_um / ekf_v_um, sqrt_p11_nm);
  // Criterion 2 and 3: EKF against each Table 2 / Table 3 entry.
  EXPECT_NEAR(relative(ekf_x_nm, col.paper_ekf_x_nm), 0.0, 0.10) << "criterion 2, EKF position";
  EXPECT_NEAR(relative(ekf_v_um, col.paper_ekf_v_um_s), 0.0, 0.20) << "criterion 3, EKF velocity";
  // Criterion 4: the baseline against the paper's ~5.15 nm / ~145 um/s.
  EXPECT_NEAR(relative(base_x_nm, 5.15), 0.0, 0.05) << "criterion 4, baseline position";
  EXPECT_NEAR(relative(base_v_um, 145.0), 0.0, 0.05) << "criterion 4, baseline velocity";
  // Criterion 5: "about 3 times" and "two orders of magnitude" better.
  EXPECT_GE(base_x_nm / ekf_x_nm, 3.0) << "criterion 5, position ratio";
  EXPECT_GE(base_v_um / ekf_v_um, 60.0) << "criterion 5, velocity ratio";
  // Criterion 7: the filter is consistent (its sigma predicts its error).
  EXPECT_NEAR(relative(ekf_x_nm, sqrt_p11_nm), 0.0, 0.15) << "criterion 7, consistency";
  // Absolute tracking: never a cycle slip (a quarter pitch would be 1000 nm).
  EXPECT_LT(r.ekf_max_position_error_m, 20e-9);
}

INSTANTIATE_TEST_SUITE_P(Seed001, Tables23, ::testing::ValuesIn(kColumns),
                         [](const ::testing::TestParamInfo<Column>& param_info) { return std::string(param_info.param.c.name); });

// --- Fig. 6: the filter-predicted steady state ---------------------------------------------

TEST(Seed001, Fig6SteadyStateCovariance) {
  // Criterion 1 from describe() (Riccati iteration, a posteriori P) and from the running
  // filter's own P at the end of a 2 s run.
  const Result r = run(kColumns[0].c);
  ASSERT_FALSE(r.faulted) << r.fault;
  const lode::Json& steady = at(ekf_describe(r.describe), "steady_state");
  ASSERT_TRUE(at(steady, "converged").as_bool());
  const auto& post = at(steady, "posterior_std").elements();
  const auto& prior = at(steady, "prior_std").elements();
  const double x_nm = post[0].as_number() * 1e9, v_um = post[1].as_number() * 1e6;
  std::printf("Fig. 6 steady state (a posteriori): sqrt P11 %.3f nm (paper 1.7), sqrt P22 %.3f um/s (paper 2.6); "
              "a priori %.3f nm, %.3f um/s (ref 1.81, 2.7); running filter at 2 s: %.3f nm, %.3f um/s\n",
              x_nm, v_um, prior[0].as_number() * 1e9, prior[1].as_number() * 1e6, r.ekf_predicted_position_m * 1e9,
              r.ekf_predicted_velocity_m_s * 1e6);
  EXPECT_NEAR(relative(x_nm, 1.7), 0.0, 0.05) << "criterion 1, position";
  EXPECT_NEAR(relative(v_um, 2.6), 0.0, 0.05) << "criterion 1, velocity";
  // The running filter reaches the same P (the R = rI Riccati is phase-invariant).
  EXPECT_NEAR(r.ekf_predicted_position_m, post[0].as_number(), 1e-6 * post[0].as_number());
  EXPECT_NEAR(r.ekf_predicted_velocity_m_s, post[1].as_number(), 1e-6 * post[1].as_number());
}

TEST(Seed001, PrintedQScalingIsTheOneThatReproducesFig6) {
  // The paper calls sigma_m^2 the "intensity" of w, with unit (m/s^3)^2, but eq. 10 fits it only
  // as the acceleration variance. Reading sigma_m^2 as the white-noise PSD makes every Q entry
  // 2 alpha smaller; that reading predicts 0.81 nm, not the paper's 1.7 nm.
  Case c = kColumns[0].c;
  c.acceleration_variance = 1e-5 / (2.0 * 200.0 * std::numbers::pi);
  c.duration_s = 0.01;
  const Result r = run(c);
  const lode::Json& steady = at(ekf_describe(r.describe), "steady_state");
  const double x_nm = at(steady, "posterior_std").elements()[0].as_number() * 1e9;
  std::printf("sigma_m^2 read as PSD: steady sqrt P11 %.3f nm (ref: 0.81 nm; paper Fig. 6: 1.7 nm)\n", x_nm);
  EXPECT_NEAR(x_nm, 0.81, 0.05 * 0.81);
  EXPECT_GT(std::abs(relative(x_nm, 1.7)), 0.4);
}

// --- Table 4: the "sub-nanometre" cases ------------------------------------------------------

/// What Table 4 prints for one row, and how far the velocity may be from it.
struct Table4Row {
  int row;
  double paper_nm, paper_um_s;
  double velocity_tolerance;
  const char* velocity_criterion;
  const char* baseline_note;  ///< said after the arctangent figures
};

/// Criterion 6 against the row, the baseline still at its ~5 nm beside it, and criterion 7.
void expect_table4_row_with_baseline(const Result& r, const Table4Row& row) {
  std::printf("Table 4 row %d: EKF %.3f nm (paper %g), %.4f um/s (paper %g); arctan %.3f nm, %.1f um/s%s; "
              "sqrt(P11) %.3f nm\n",
              row.row, r.ekf_position_m * 1e9, row.paper_nm, r.ekf_velocity_m_s * 1e6, row.paper_um_s,
              r.baseline_position_m * 1e9, r.baseline_velocity_m_s * 1e6, row.baseline_note,
              r.ekf_predicted_position_m * 1e9);
  EXPECT_NEAR(relative(r.ekf_position_m * 1e9, row.paper_nm), 0.0, 0.15) << "criterion 6, position";
  EXPECT_NEAR(relative(r.ekf_velocity_m_s * 1e6, row.paper_um_s), 0.0, row.velocity_tolerance)
      << row.velocity_criterion;
  EXPECT_NEAR(relative(r.baseline_position_m * 1e9, 5.15), 0.0, 0.05) << "the baseline stays at ~5 nm";
  EXPECT_NEAR(relative(r.ekf_position_m, r.ekf_predicted_position_m), 0.0, 0.15) << "criterion 7, consistency";
}

TEST(Seed001, Table4Row1QuasiStatic) {
  // 0.1 um at 2 Hz, sigma_m^2 = 1e-9, 20 kHz: paper 0.6 nm / 0.08 um/s.
  const Result r = run({"t4_row1", 0.1e-6, 2.0, 0.0, 20000.0, 1e-9});
  ASSERT_FALSE(r.faulted) << r.fault;
  expect_table4_row_with_baseline(r, {1, 0.6, 0.08, 0.30, "criterion 6, velocity (30 % on row 1)", ""});
}

TEST(Seed001, Table4Row2HundredKilohertz) {
  // 1 um at 2 Hz, sigma_m^2 = 1e-5, 100 kHz (1 s run): paper 0.81 nm / 1.22 um/s.
  const Result r = run({"t4_row2", 1e-6, 2.0, 0.0, 100000.0, 1e-5, 1.0});
  ASSERT_FALSE(r.faulted) << r.fault;
  expect_table4_row_with_baseline(
      r, {2, 0.81, 1.22, 0.15, "criterion 6, velocity", " (backward difference at 100 kHz)"});
}

TEST(Seed001, Table4Row3TwentyKilohertz) {
  // 1 um at 2 Hz, sigma_m^2 = 1e-5, 20 kHz: paper 1.54 nm / 1.69 um/s (= Table 2/3 column 2).
  const Result r = run({"t4_row3", 1e-6, 2.0});
  ASSERT_FALSE(r.faulted) << r.fault;
  std::printf("Table 4 row 3: EKF %.3f nm (paper 1.54), %.3f um/s (paper 1.69)\n", r.ekf_position_m * 1e9,
              r.ekf_velocity_m_s * 1e6);
  EXPECT_NEAR(relative(r.ekf_position_m * 1e9, 1.54), 0.0, 0.15) << "criterion 6, position";
  EXPECT_NEAR(relative(r.ekf_velocity_m_s * 1e6, 1.69), 0.0, 0.15) << "criterion 6, velocity";
}

// --- Seed spread: the criteria are not a lucky seed ------------------------------------------

TEST(Seed001, TenSeedsOfTheFirstColumn) {
  // 5 Hz, 1 um over seeds 1-10: every seed meets criteria 2-5 and 7, and the spread is shown.
  double min_x = 1e9, max_x = 0, min_v = 1e9, max_v = 0, sum_x = 0, sum_v = 0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    Case c = kColumns[0].c;
    c.seed = seed;
    const Result r = run(c);
    ASSERT_FALSE(r.faulted) << r.fault;
    const double x = r.ekf_position_m * 1e9, v = r.ekf_velocity_m_s * 1e6;
    min_x = std::min(min_x, x), max_x = std::max(max_x, x), sum_x += x;
    min_v = std::min(min_v, v), max_v = std::max(max_v, v), sum_v += v;
    EXPECT_NEAR(relative(x, 1.57), 0.0, 0.10) << "seed " << seed;
    EXPECT_NEAR(relative(v, 1.77), 0.0, 0.20) << "seed " << seed;
    EXPECT_NEAR(relative(r.baseline_position_m * 1e9, 5.15), 0.0, 0.05) << "seed " << seed;
    EXPECT_NEAR(relative(r.baseline_velocity_m_s * 1e6, 145.0), 0.0, 0.05) << "seed " << seed;
    EXPECT_NEAR(relative(x, r.ekf_predicted_position_m * 1e9), 0.0, 0.15) << "seed " << seed;
  }
  std::printf("5 Hz 1 um, seeds 1-10: EKF position %.3f .. %.3f nm (mean %.3f, paper 1.57), velocity %.3f .. %.3f "
              "um/s (mean %.3f, paper 1.77)\n",
              min_x, max_x, sum_x / 10, min_v, max_v, sum_v / 10);
}

}  // namespace
