// Numbers written into a block's YAML parameters so that they read back exactly ("%.17g"):
// tests that compare a block with a reference computed from the same numbers need them bit
// for bit.
#pragma once

#include <array>
#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

namespace lode::estimator_testing {

inline std::string exact(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

/// [v0, v1, ...] with every number exact().
inline std::string exact_list(const std::vector<double>& values) {
  std::string s = "[";
  for (std::size_t i = 0; i < values.size(); ++i) s += (i ? ", " : "") + exact(values[i]);
  return s + "]";
}

template <std::size_t N>
std::string exact_list(const std::array<double, N>& values) {
  return exact_list(std::vector<double>(values.begin(), values.end()));
}

}  // namespace lode::estimator_testing
