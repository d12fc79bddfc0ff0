// What the reference generators source.step, source.ramp, source.sine and source.zigzag share:
// their output (the `out` port, its elements from `names`/`units` and the per-element `offset`
// it rests at), their per-element runtime parameters (`lode set offset.x`), and reading time
// parameters against the scheduled tick time.
//
// The family's library (lode_source_common); a source links it, derives from
// source::ElementSource ("element_source.hpp"), which holds its SourceOutput, and includes
// "source_elements.hpp". Everything here runs in configure(), except where a function says
// RT-safe.
#pragma once

#include <cstdint>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"

namespace lode::plugins::source {

/// A per-element list under `key` with exactly `n` entries. Without a fallback the key is
/// required; with one, an absent key gives n copies of it.
std::vector<double> read_per_element(Params& params, std::string_view key, std::size_t n,
                                     std::optional<double> fallback = std::nullopt);

/// Largest time a parameter may name: keeps every time in int64 nanoseconds with margin.
inline constexpr double kMaxTimeS = 1.0e9;

/// Seconds (a validated parameter) to integer nanoseconds, so that comparisons against the
/// scheduled tick time are exact: a step at time_s = 0.1 happens on the cycle whose
/// scheduled time is >= 100000000 ns, never one cycle early or late because of rounding.
std::int64_t seconds_to_ns(double seconds);

/// Reads a time parameter in seconds that must lie in [0, kMaxTimeS]; returns nanoseconds.
/// Without a fallback the key is required.
std::int64_t read_time_ns(Params& params, std::string_view key, std::optional<double> fallback_s = std::nullopt);

/// Seconds elapsed since `start_ns` at scheduled time `time_ns` (negative before the start).
/// The difference is taken in integers first, so long runs lose no resolution. RT-safe.
inline double elapsed_s(std::int64_t time_ns, std::int64_t start_ns) noexcept {
  return static_cast<double>(time_ns - start_ns) * 1e-9;
}

/// Runtime parameters (`lode set`) that are one number per element of a per-element list:
/// `<key>.<element name>`, e.g. `offset.x`. The tunable index is group * elements + element,
/// with the groups in the order they were added.
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

  /// Configure time: a group over `values`, the block's own per-element list, which it
  /// outlives (blocks are neither copied nor moved).
  void add(Group group, std::vector<double>& values);

  /// Off the RT thread, after configure().
  [[nodiscard]] std::vector<Tunable> list(const Elements& elements) const;
  /// The current value; 0 for an index out of range. RT-safe.
  [[nodiscard]] double value(std::size_t index, std::size_t elements) const noexcept;
  /// Which group and element an index names; refuses (false, with `why`) an index out of range
  /// and a value that is not finite. RT-safe: the command path has checked the range already,
  /// this also catches NaN and infinities from direct callers.
  bool locate(std::size_t index, std::size_t elements, double value, std::size_t& group, std::size_t& element,
              const char*& why) const noexcept;
  /// Stores a located value in its group's list. RT-safe.
  void store(std::size_t group, std::size_t element, double value) noexcept { (*groups_[group].values)[element] = value; }

 private:
  struct Bound {
    Group group;
    std::vector<double>* values;
  };
  std::vector<Bound> groups_;
};

/// The output of a source: `out` with the elements of `names`/`units`, the per-element
/// `offset`, and the per-element runtime parameters, `offset.<element>` first (group 0).
class SourceOutput {
 public:
  static constexpr std::size_t kOffsetGroup = 0;

  /// configure(), first: reads `names` (required, unique, non-empty), `units` (required, one
  /// per name) and `offset` (per element, default 0); problems are recorded at their key.
  /// `offset_description` describes the offset's runtime parameter.
  void read(Params& params, std::string offset_description);
  /// configure(): one more group of per-element runtime parameters over `values`.
  void add_tunable(ElementTunables::Group group, std::vector<double>& values) {
    tunables_.add(std::move(group), values);
  }
  /// configure(), last: declares `out`; the result of configure().
  Status declare(ConfigureContext& ctx);

  [[nodiscard]] std::size_t size() const noexcept { return elements_.size(); }
  [[nodiscard]] const std::vector<double>& offset() const noexcept { return offset_; }
  /// The output port, for step().
  [[nodiscard]] OutputPort& port() noexcept { return out_; }
  /// out = offset: activate(), and before a source starts. RT-safe.
  void write_offset() noexcept;
  /// describe(): the element count and the offsets.
  void describe(Json& out) const;

  /// The Block tunables API over the groups; set_tunable() stores the value (a source with
  /// more to do on a change uses locate() and store()).
  [[nodiscard]] std::vector<Tunable> tunables() const { return tunables_.list(elements_); }
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept { return tunables_.value(index, size()); }
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept;
  bool locate(std::size_t index, double value, std::size_t& group, std::size_t& element,
              const char*& why) const noexcept {
    return tunables_.locate(index, size(), value, group, element, why);
  }
  void store(std::size_t group, std::size_t element, double value) noexcept { tunables_.store(group, element, value); }

 private:
  OutputPort out_;
  Elements elements_;
  std::vector<double> offset_;
  ElementTunables tunables_;
};

}  // namespace lode::plugins::source
