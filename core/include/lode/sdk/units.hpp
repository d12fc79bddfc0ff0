// SI units carried by port elements, as short canonical strings.
//
// Units are compared as strings after canonicalisation at load time ("N.m" and "N*m" are
// the same unit); the cycle never looks at them. kAnyUnit on an input element accepts any
// source unit (used by generic blocks such as a logger or a gain of 1).
#pragma once

#include <string>
#include <string_view>

namespace lode {

inline constexpr std::string_view kAnyUnit = "*";
inline constexpr std::string_view kDimensionless = "1";

/// Canonical spelling of a unit string: '*' and '.' and ' ' between factors become '*',
/// "rad/s^2" and "rad/s2" are the same, empty means dimensionless.
std::string canonical_unit(std::string_view unit);

/// True when a source element with unit `source` may feed an input declared `expected`.
bool units_compatible(std::string_view source, std::string_view expected);

}  // namespace lode
