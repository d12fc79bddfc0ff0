// Parameters given per measured axis (configure(): off the RT thread).
#pragma once

#include <cstddef>
#include <string_view>
#include <vector>

#include "lode/sdk/params.hpp"

namespace lode::plugins::estimator {

/// A per-axis list that may also be written as one number for every axis: one number is spread
/// to `axes`; any other count but `axes` is reported on `key`, and the list is padded or cut to
/// `axes` so that the caller may still index it.
std::vector<double> per_axis(Params& params, std::string_view key, std::vector<double> values, std::size_t axes);

}  // namespace lode::plugins::estimator
