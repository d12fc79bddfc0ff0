// Measurements the filter plugins' tests share: the amplitude and phase of one frequency in a
// sampled signal, a filter's steady-state gain measured with a sine, the bank's `enabled`
// runtime parameter, and that running cycles (inputs written, runtime parameters set)
// allocates nothing.
#pragma once

#include <complex>
#include <functional>
#include <vector>

#include "lode/sdk/json.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/sdk/math/discretize.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins::filter::testing {

/// The f_hz component of y[k] (sampled at rate_hz) by least squares on sin/cos over the
/// samples, y ~ a sin + b cos, as a + jb: its magnitude is the amplitude.
std::complex<double> component(const std::vector<double>& y, double f_hz, double rate_hz);

/// A filtered channel's section as describe() reports it: b and a (a[0] = 1) of
/// H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2).
lode::math::TransferFunction described_section(const Json& channel);

/// Channel 0's steady-state gain at f_hz: activates the filter, runs a unit sine through it,
/// skips `settle_cycles`, then fits the output's f_hz component over 4 s.
double measured_gain(lode::testing::BlockHarness& h, double f_hz, double rate_hz, int settle_cycles);

/// On an activated filter, `cycles` cycles of `cycle(k)` (write the inputs, set runtime
/// parameters) and step(): every step() succeeds and none of it allocates.
void expect_cycles_allocate_nothing(lode::testing::BlockHarness& h, int cycles, const std::function<void(int k)>& cycle);

/// The same with runtime parameters: `cycle(block, k)` sets them (and writes the inputs) and
/// returns how many of its set_tunable() calls were accepted; over all cycles that must be
/// `expected_accepted`.
void expect_set_tunables_allocate_nothing(lode::testing::BlockHarness& h, int cycles, int expected_accepted,
                                          const std::function<int(Tunables& block, int k)>& cycle);

/// `t` is the bank's `enabled` switch: a bool, an integer in [0, 1].
void expect_enabled_tunable(const Tunable& t);

}  // namespace lode::plugins::filter::testing
