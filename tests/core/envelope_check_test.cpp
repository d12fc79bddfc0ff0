// The envelope's check() on its own: a flat pass handles the cycles where every value is
// inside and hands anything else to the per-limit reference, so whatever the flat pass
// leaves behind (previous values for rate limits, the start of a run of invalid samples)
// must be what the reference would have left. Each test here fails if the flat pass forgets
// one of them; the last compares check() with a model of the specification over random runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../core/src/envelope.hpp"

namespace {

using lode::Tick;
using lode::pipeline_detail::Envelope;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz

Tick tick_at(std::uint64_t cycle) {
  Tick t;
  t.cycle = cycle;
  t.time_ns = static_cast<std::int64_t>(cycle) * kPeriodNs;
  t.dt_s = 1e-3;
  return t;
}

/// Names and units of `n` elements "e0", "e1", ... in metres; kept alive for the envelopes.
const lode::Elements& elements_of(std::size_t n) {
  static const std::vector<lode::Elements> all = [] {
    std::vector<lode::Elements> e(4);
    for (std::size_t k = 0; k < e.size(); ++k)
      for (std::size_t i = 0; i < k; ++i) e[k].push_back({"e" + std::to_string(i), "m"});
    return e;
  }();
  return all.at(n);
}

Envelope::Limit limit_on(const std::string& signal, const std::vector<double>& storage) {
  Envelope::Limit l;
  l.signal = signal;
  l.data = storage.data();
  l.elements = &elements_of(storage.size());
  l.min.assign(storage.size(), -kInf);
  l.max.assign(storage.size(), kInf);
  l.max_rate.assign(storage.size(), kInf);
  return l;
}

TEST(EnvelopeCheck, TwoShortDropoutsWithGoodDataBetweenAreEachWithinTheBudget) {
  // max_invalid 30 ms; NaN for 20 ms, good for 10 ms, NaN for 20 ms again. If a good cycle on
  // the flat pass did not end the first run of invalid samples, the second would count from
  // the first and fault at 30 ms after it.
  std::vector<double> pose{0.0, 0.0};
  Envelope::Limit l = limit_on("glsdc.pose", pose);
  l.max_invalid_ns = 30 * kPeriodNs;
  Envelope env;
  env.add(l);
  env.reset();
  for (std::uint64_t k = 0; k < 60; ++k) {
    const bool invalid = (k >= 5 && k < 25) || (k >= 35 && k < 55);
    pose[1] = invalid ? kNaN : 1e-3;
    ASSERT_TRUE(env.check(tick_at(k))) << "cycle " << k << ": " << env.violation_text();
  }
  // Control: one dropout longer than the budget faults 30 ms + 1 cycle after it began.
  Envelope long_dropout;
  long_dropout.add(l);
  long_dropout.reset();
  std::uint64_t fault = 0;
  for (std::uint64_t k = 0; k < 100 && fault == 0; ++k) {
    pose[1] = k >= 5 ? kNaN : 1e-3;
    if (!long_dropout.check(tick_at(k))) fault = k;
  }
  EXPECT_EQ(fault, 5u + 31u) << long_dropout.violation_text();
  EXPECT_NE(long_dropout.violation_text().find("glsdc.pose has been invalid (non-finite) for 31 ms"), std::string::npos)
      << long_dropout.violation_text();
}

TEST(EnvelopeCheck, ARateIsJudgedAgainstTheValueOfTheCycleBefore) {
  // A slope of 1 m/s under a 2 m/s limit never faults however long it runs on the flat pass;
  // a jump of 3 mm in one 1 ms cycle (3 m/s) faults in that cycle. A flat pass that did not
  // keep the previous value would compare against a stale one and fault on the slope.
  std::vector<double> x{0.0};
  Envelope::Limit l = limit_on("ref.out", x);
  l.max_rate[0] = 2.0;
  Envelope env;
  env.add(l);
  env.reset();
  std::uint64_t fault = 0;
  for (std::uint64_t k = 0; k < 500 && fault == 0; ++k) {
    x[0] = 1e-3 * static_cast<double>(k) + (k >= 400 ? 3e-3 : 0.0);
    if (!env.check(tick_at(k))) fault = k;
  }
  EXPECT_EQ(fault, 400u) << env.violation_text();
  EXPECT_NE(env.violation_text().find("ref.out.e0 changes at 4 m/s"), std::string::npos) << env.violation_text();
}

TEST(EnvelopeCheck, AnInfiniteValueWithABudgetIsInvalidNotInside) {
  // Unbounded but with an invalid budget: +inf is not a value inside, it starts the budget.
  std::vector<double> v{0.0};
  Envelope::Limit l = limit_on("kf.pose", v);
  l.max_invalid_ns = 2 * kPeriodNs;
  Envelope env;
  env.add(l);
  env.reset();
  std::uint64_t fault = 0;
  for (std::uint64_t k = 0; k < 20 && fault == 0; ++k) {
    v[0] = k >= 10 ? kInf : 0.0;
    if (!env.check(tick_at(k))) fault = k;
  }
  EXPECT_EQ(fault, 13u) << env.violation_text();
}

/// The specification, limit by limit, written independently of Envelope: the first breach in
/// the order limits were added, elements in order; state moves on only for limits inside.
struct ModelLimit {
  std::vector<double> min, max, max_rate, previous;
  bool have_previous = false;
  std::int64_t max_invalid_ns = -1, invalid_since_ns = -1;
};

bool model_check(std::vector<ModelLimit>& limits, const std::vector<std::vector<double>>& values, const Tick& t) {
  for (std::size_t l = 0; l < limits.size(); ++l) {
    ModelLimit& m = limits[l];
    const std::vector<double>& v = values[l];
    bool all_finite = true;
    for (double e : v) all_finite = all_finite && std::isfinite(e);
    if (m.max_invalid_ns >= 0) {
      if (all_finite)
        m.invalid_since_ns = -1;
      else if (m.invalid_since_ns < 0)
        m.invalid_since_ns = t.time_ns;
      if (m.invalid_since_ns >= 0 && t.time_ns - m.invalid_since_ns > m.max_invalid_ns) return false;
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!std::isfinite(v[i]) && m.max_invalid_ns >= 0) continue;
      if (!(v[i] >= m.min[i]) || !(v[i] <= m.max[i])) return false;
      if (m.have_previous && std::isfinite(m.previous[i]) && std::isfinite(v[i]) &&
          std::abs(v[i] - m.previous[i]) / t.dt_s > m.max_rate[i])
        return false;
    }
    m.previous = v;
    m.have_previous = true;
  }
  return true;
}

TEST(EnvelopeCheck, AgreesWithTheSpecificationOverRandomRuns) {
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int faults = 0;
  for (int run = 0; run < 400; ++run) {
    const std::size_t n_limits = 1 + rng() % 3;
    std::vector<std::vector<double>> storage(n_limits);
    std::vector<ModelLimit> model(n_limits);
    Envelope env;
    for (std::size_t l = 0; l < n_limits; ++l) {
      const std::size_t n = 1 + rng() % 3;
      storage[l].assign(n, 0.0);
      Envelope::Limit lim = limit_on("s" + std::to_string(l) + ".out", storage[l]);
      for (std::size_t i = 0; i < n; ++i) {
        if (unit(rng) < 0.6) lim.min[i] = -1.0;
        if (unit(rng) < 0.6) lim.max[i] = 1.0;
        if (unit(rng) < 0.4) lim.max_rate[i] = 400.0;  // 0.4 per 1 ms cycle
      }
      if (unit(rng) < 0.5) lim.max_invalid_ns = static_cast<std::int64_t>(rng() % 6) * kPeriodNs;
      model[l].min = lim.min;
      model[l].max = lim.max;
      model[l].max_rate = lim.max_rate;
      model[l].max_invalid_ns = lim.max_invalid_ns;
      model[l].previous.assign(n, 0.0);
      env.add(lim);
    }
    env.reset();
    // Mostly small steps inside [-1, 1], now and then a jump, a value outside, NaN or inf.
    for (std::uint64_t k = 0; k < 200; ++k) {
      for (auto& s : storage)
        for (double& e : s) {
          const double u = unit(rng);
          if (u < 0.003) e = kNaN;
          else if (u < 0.004) e = (rng() & 1) ? kInf : -kInf;
          else if (u < 0.006) e = 1.5 * (unit(rng) - 0.5) * 2.0;
          else if (u < 0.008) e = 0.9 * (unit(rng) - 0.5) * 2.0;
          else if (!std::isfinite(e) && u < 0.5) e = 0.0;
          else if (std::isfinite(e)) e = std::clamp(e + 0.05 * (unit(rng) - 0.5), -0.95, 0.95);
        }
      const Tick t = tick_at(k);
      const bool expected = model_check(model, storage, t);
      const bool got = env.check(t);
      ASSERT_EQ(got, expected) << "run " << run << ", cycle " << k << ": check() " << (got ? "passed" : "faulted")
                               << ", the specification " << (expected ? "passes" : "faults") << " ("
                               << env.violation_text() << ")";
      if (!got) {
        ++faults;
        break;
      }
    }
  }
  // The runs must exercise both outcomes, or the comparison proves little.
  EXPECT_GT(faults, 50);
  EXPECT_LT(faults, 350);
}

}  // namespace
