#include "lode/sdk/units.hpp"

#include <algorithm>
#include <cctype>

#include "lode/sdk/port.hpp"
#include "lode/sdk/plugin.hpp"

namespace lode {

std::string canonical_unit(std::string_view unit) {
  std::string out;
  out.reserve(unit.size());
  for (std::size_t i = 0; i < unit.size(); ++i) {
    const char c = unit[i];
    if (c == ' ' || c == '.' || c == '*') {
      if (!out.empty() && out.back() != '*') out.push_back('*');
      continue;
    }
    if (c == '^') continue;  // "s^2" == "s2"
    out.push_back(c);
  }
  while (!out.empty() && out.back() == '*') out.pop_back();
  if (out.empty()) return std::string(kDimensionless);
  if (out == "*") return std::string(kAnyUnit);
  return out;
}

bool units_compatible(std::string_view source, std::string_view expected) {
  if (expected == kAnyUnit || source == kAnyUnit) return true;
  return canonical_unit(source) == canonical_unit(expected);
}

Elements numbered_elements(const std::string& prefix, std::size_t n, const std::string& unit) {
  Elements e;
  e.reserve(n);
  for (std::size_t i = 0; i < n; ++i) e.push_back({prefix + std::to_string(i), unit});
  return e;
}

const char* to_string(PluginKind kind) {
  switch (kind) {
    case PluginKind::block: return "block";
    case PluginKind::io: return "io";
    case PluginKind::plant: return "plant";
    case PluginKind::sensor: return "sensor";
    case PluginKind::process: return "process";
  }
  return "unknown";
}

}  // namespace lode
