// Checks the reference sources' tests share for their per-element runtime parameters
// (`lode set offset.x`, ...): what they are called, that refusing a value changes nothing, and
// that setting them allocates nothing.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/sdk/testing/harness.hpp"

namespace lode::plugins::source::testing {

/// The block's runtime parameters are exactly these {name, unit}, in this order.
void expect_tunables(const Tunables& block, const std::vector<std::pair<std::string, std::string>>& names_and_units);

/// Two sources configured alike run 300 cycles; at cycle 100 `refuse` sets values the first
/// must refuse (its own expectations): the outputs stay identical throughout.
void expect_refusals_change_nothing(const std::string& plugin, const std::string& params, double rate_hz,
                                    const std::function<void(Tunables& block)>& refuse);

/// On an activated source, 1000 cycles of set_tunable(index, a or b), which must be accepted,
/// a NaN at the same index and an index out of range, which are refused, and step():
/// none of it allocates.
void expect_set_tunable_allocates_nothing(lode::testing::BlockHarness& h, std::size_t index, double a, double b);

}  // namespace lode::plugins::source::testing
