// Numbers in messages: the shortest text that keeps `significant_digits` digits ("%g").
#pragma once

#include <cstdio>
#include <string>

namespace lode {

inline std::string number_text(double value, int significant_digits = 6) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.*g", significant_digits, value);
  return buffer;
}

}  // namespace lode
