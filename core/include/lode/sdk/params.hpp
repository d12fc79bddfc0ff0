// Typed, located access to a block's or model's parameters.
//
// Each getter either returns the value or records a Diagnostic at the exact YAML position
// (file:line:column) and returns a harmless default, so configure() can read everything,
// report every problem at once, and return Status::error if params.ok() is false.
// Every key read is remembered: after configure() the pipeline reports keys that nobody
// read ("unknown parameter", usually a typo) and keys read but not documented by the
// plugin's descriptor (a plugin bug caught by the tests).
//
// Units live in key names (mass_kg, rate_hz, noise_std_v), following PX4's *_m_s2 style,
// so a YAML file is self-describing without a unit parser.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/diagnostics.hpp"

namespace lode {

namespace detail {
struct ParamsNode;  // wraps a YAML node; defined in core
}

class Params {
 public:
  Params();
  ~Params();
  Params(const Params&);
  Params& operator=(const Params&);

  /// @name Scalars. Without a fallback the key is required.
  //@{
  double number(std::string_view key);
  double number(std::string_view key, double fallback);
  std::int64_t integer(std::string_view key);
  std::int64_t integer(std::string_view key, std::int64_t fallback);
  bool flag(std::string_view key, bool fallback);
  std::string text(std::string_view key);
  std::string text(std::string_view key, std::string_view fallback);
  /// A file named by the configuration: text, a relative path taken relative to the directory
  /// of the file the key is written in, so a pipeline and the files it names can move
  /// together and `lode run` works from any directory. Absent: `fallback`, as given.
  std::string file_path(std::string_view key, std::string_view fallback);
  /// One of `allowed`; anything else is reported with the list of allowed values.
  std::string choice(std::string_view key, const std::vector<std::string>& allowed,
                     std::optional<std::string_view> fallback = std::nullopt);
  //@}

  /// @name Sequences. `size` (if given) is enforced; fallback makes the key optional.
  //@{
  std::vector<double> numbers(std::string_view key, std::optional<std::size_t> size = std::nullopt);
  std::vector<double> numbers(std::string_view key, std::vector<double> fallback,
                              std::optional<std::size_t> size = std::nullopt);
  /// A list given per element (per axis, say) that may also be one number for all: one number
  /// is spread to `count`; any other length but `count` is reported on `key` ("expected one
  /// number or N (one per `each`), got M") and the list is padded or cut to `count`, so the
  /// caller may still index it.
  std::vector<double> one_or_each(std::string_view key, std::vector<double> values, std::size_t count,
                                  std::string_view each);
  std::vector<std::int64_t> integers(std::string_view key, std::vector<std::int64_t> fallback);
  std::vector<std::string> texts(std::string_view key, std::vector<std::string> fallback);
  //@}

  /// @name Nested maps and lists of maps.
  //@{
  Params child(std::string_view key);                  ///< required map
  std::optional<Params> optional_child(std::string_view key);
  std::vector<Params> items(std::string_view key);     ///< required non-empty list of maps
  //@}

  [[nodiscard]] bool has(std::string_view key) const;
  /// Record a problem at the key's position (or at this map if the key is absent).
  void fail(std::string_view key, std::string message);
  /// Record a problem at this map's position.
  void fail(std::string message);
  /// Shorthand: if !condition, fail(key, message). Returns condition.
  bool check(bool condition, std::string_view key, std::string message);

  [[nodiscard]] bool ok() const;                 ///< no problem recorded in this tree so far
  [[nodiscard]] const std::string& path() const;  ///< dotted path of this map
  [[nodiscard]] SourceLocation location(std::string_view key = {}) const;

  /// Keys of this map in file order (for generic blocks that iterate).
  [[nodiscard]] std::vector<std::string> keys() const;

  // Used by the core to build and check parameter trees.
  explicit Params(std::shared_ptr<detail::ParamsNode> node);
  [[nodiscard]] const std::shared_ptr<detail::ParamsNode>& node() const { return node_; }

 private:
  std::shared_ptr<detail::ParamsNode> node_;
};

}  // namespace lode
