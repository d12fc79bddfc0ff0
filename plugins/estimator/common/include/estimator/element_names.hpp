// Names and units of the elements an estimator reads and writes, derived from the elements
// of its inputs (configure(): off the RT thread).
#pragma once

#include <string>

#include "lode/sdk/port.hpp"

namespace lode::plugins::estimator {

/// "a [u], b [v]" for messages; "(none)" when there is no element.
std::string element_list(const Elements& elements);

/// <name>_dot [<unit>/s] for every element: the rates of measured positions.
Elements rate_elements(const Elements& positions);

/// <name>_ddot [<unit>/s^2] for every element: the accelerations of measured positions.
Elements acceleration_elements(const Elements& positions);

}  // namespace lode::plugins::estimator
