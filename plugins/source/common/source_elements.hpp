// Shared by the reference generators source.step, source.ramp, source.sine, source.zigzag:
// reading the common parameters (names, units, offset) and handling scheduled time.
//
// Header-only and not a plugin (no CMakeLists.txt here): each source includes it with
// `#include "../common/source_elements.hpp"`. Everything here runs in configure(), except
// elapsed_s() and the ElementTunables lookups, which are RT-safe.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"
#include "lode/sdk/text.hpp"

namespace lode::plugins::source {

/// The output elements of a source and its per-element resting value.
struct SourceElements {
  Elements elements;           ///< from `names` and `units`
  std::vector<double> offset;  ///< from `offset`, default 0 per element

  [[nodiscard]] std::size_t size() const { return elements.size(); }
};

/// Reads `names` (required, unique, non-empty), `units` (required, same length) and
/// `offset` (per element, default 0). Problems are recorded in `params` at their key.
inline SourceElements read_source_elements(Params& params) {
  SourceElements out;
  const std::vector<std::string> names = params.texts("names", {});
  const std::vector<std::string> units = params.texts("units", {});
  if (!params.has("names") || names.empty()) {
    params.fail("names", "a non-empty list of element names is required, e.g. [x, y, theta_z]");
  }
  std::set<std::string> seen;
  for (const auto& name : names) {
    if (name.empty()) params.fail("names", "element names must not be empty");
    if (!seen.insert(name).second) params.fail("names", "duplicate element name '" + name + "'");
  }
  if (!params.has("units")) {
    params.fail("units", "a list of SI units, one per name, is required, e.g. [m, m, rad]");
  } else if (units.size() != names.size()) {
    params.fail("units", "expected " + std::to_string(names.size()) + " units (one per name), got " +
                             std::to_string(units.size()));
  }
  for (std::size_t i = 0; i < names.size(); ++i) {
    out.elements.push_back({names[i], i < units.size() ? units[i] : std::string("1")});
  }
  out.offset = params.numbers("offset", std::vector<double>(names.size(), 0.0), names.size());
  out.offset.resize(names.size(), 0.0);
  return out;
}

/// A per-element list under `key` with exactly `n` entries. Without a fallback the key is
/// required; with one, an absent key gives n copies of it.
inline std::vector<double> read_per_element(Params& params, std::string_view key, std::size_t n,
                                            std::optional<double> fallback = std::nullopt) {
  std::vector<double> values = fallback ? params.numbers(key, std::vector<double>(n, *fallback), n)
                                        : params.numbers(key, n);
  values.resize(n, 0.0);
  return values;
}

/// Largest time a parameter may name: keeps every time in int64 nanoseconds with margin.
inline constexpr double kMaxTimeS = 1.0e9;

/// Seconds (a validated parameter) to integer nanoseconds, so that comparisons against the
/// scheduled tick time are exact: a step at time_s = 0.1 happens on the cycle whose
/// scheduled time is >= 100000000 ns, never one cycle early or late because of rounding.
inline std::int64_t seconds_to_ns(double seconds) {
  return static_cast<std::int64_t>(std::llround(seconds * 1e9));
}

/// Reads a time parameter in seconds that must lie in [0, kMaxTimeS]; returns nanoseconds.
/// Without a fallback the key is required.
inline std::int64_t read_time_ns(Params& params, std::string_view key,
                                 std::optional<double> fallback_s = std::nullopt) {
  const double seconds = fallback_s ? params.number(key, *fallback_s) : params.number(key);
  if (!(seconds >= 0.0 && seconds <= kMaxTimeS)) {
    params.fail(key, "must be within [0, 1e9] s, got " + number_text(seconds));
    return 0;
  }
  return seconds_to_ns(seconds);
}

/// Seconds elapsed since `start_ns` at scheduled time `time_ns` (negative before the start).
/// The difference is taken in integers first, so long runs lose no resolution. RT-safe.
inline double elapsed_s(std::int64_t time_ns, std::int64_t start_ns) noexcept {
  return static_cast<double>(time_ns - start_ns) * 1e-9;
}

/// Runtime parameters (`lode set`) that are one number per element of a per-element list
/// key: `<key>.<element name>`, e.g. `offset.x`. The tunable index is
/// group * elements + element, with the groups in the order they were added.
class ElementTunables {
 public:
  struct Group {
    std::string key;          ///< the YAML key, e.g. "amplitude"
    std::string unit_suffix;  ///< appended to the element unit ("" or "/s"); unit_override wins
    std::string unit_override;
    double min = -1e300;
    double max = 1e300;
    std::string description;
  };

  /// Configure time.
  void add(Group group) { groups_.push_back(std::move(group)); }

  /// Off the RT thread, after configure().
  [[nodiscard]] std::vector<Tunable> list(const Elements& elements) const {
    std::vector<Tunable> out;
    for (const Group& g : groups_) {
      for (const Element& e : elements) {
        Tunable t;
        t.name = g.key + "." + e.name;
        t.unit = g.unit_override.empty() ? e.unit + g.unit_suffix : g.unit_override;
        t.min = g.min;
        t.max = g.max;
        t.description = g.description + " of " + e.name;
        out.push_back(std::move(t));
      }
    }
    return out;
  }

  /// Which group and element an index names; false if out of range. RT-safe.
  [[nodiscard]] bool locate(std::size_t index, std::size_t elements, std::size_t& group,
                            std::size_t& element) const noexcept {
    if (elements == 0 || index >= groups_.size() * elements) return false;
    group = index / elements;
    element = index % elements;
    return true;
  }

 private:
  std::vector<Group> groups_;
};

/// The common refusals of a per-element source parameter; RT-safe. The command path has
/// checked the range already; this also catches NaN and infinities from direct callers.
inline bool accept_finite(double value, const char*& why) noexcept {
  if (!std::isfinite(value)) {
    why = "the value must be finite";
    return false;
  }
  return true;
}

}  // namespace lode::plugins::source
