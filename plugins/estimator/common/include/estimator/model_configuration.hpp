// Reading a ModelEstimator's inputs and noise parameters (configure(): off the RT thread).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"

namespace lode::plugins::nonlinear {

/// The index in `source` of every element of `wanted`: by name (units must be compatible),
/// or by position when no name matches and the sizes agree. Returns false with `why`.
bool pick_elements(const Elements& wanted, const Elements& source, std::vector<std::size_t>& index,
                   std::string& why);

/// A covariance given as one number (c I), n numbers (its diagonal) or n*n numbers (row-major).
/// Symmetric, and positive definite (or semidefinite when `semidefinite`); problems go to params.
Eigen::MatrixXd covariance_from(Params& params, std::string_view key, const std::vector<double>& values,
                                std::size_t n, bool semidefinite);

}  // namespace lode::plugins::nonlinear
