#include "source_elements.hpp"

#include <cmath>
#include <set>
#include <utility>

#include "lode/sdk/text.hpp"

namespace lode::plugins::source {

std::vector<double> read_per_element(Params& params, std::string_view key, std::size_t n,
                                     std::optional<double> fallback) {
  std::vector<double> values = fallback ? params.numbers(key, std::vector<double>(n, *fallback), n)
                                        : params.numbers(key, n);
  values.resize(n, 0.0);
  return values;
}

std::int64_t seconds_to_ns(double seconds) { return static_cast<std::int64_t>(std::llround(seconds * 1e9)); }

std::int64_t read_time_ns(Params& params, std::string_view key, std::optional<double> fallback_s) {
  const double seconds = fallback_s ? params.number(key, *fallback_s) : params.number(key);
  if (!(seconds >= 0.0 && seconds <= kMaxTimeS)) {
    params.fail(key, "must be within [0, 1e9] s, got " + number_text(seconds));
    return 0;
  }
  return seconds_to_ns(seconds);
}

void ElementTunables::add(Group group, std::vector<double>& values) {
  groups_.push_back({std::move(group), &values});
}

std::vector<Tunable> ElementTunables::list(const Elements& elements) const {
  std::vector<Tunable> out;
  for (const Bound& b : groups_) {
    const Group& g = b.group;
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

double ElementTunables::value(std::size_t index, std::size_t elements) const noexcept {
  if (elements == 0 || index >= groups_.size() * elements) return 0.0;
  return (*groups_[index / elements].values)[index % elements];
}

bool ElementTunables::locate(std::size_t index, std::size_t elements, double value, std::size_t& group,
                             std::size_t& element, const char*& why) const noexcept {
  if (elements == 0 || index >= groups_.size() * elements) {
    why = "no such parameter";
    return false;
  }
  if (!std::isfinite(value)) {
    why = "the value must be finite";
    return false;
  }
  group = index / elements;
  element = index % elements;
  return true;
}

void SourceOutput::read(Params& params, std::string offset_description) {
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
  elements_.clear();
  for (std::size_t i = 0; i < names.size(); ++i) {
    elements_.push_back({names[i], i < units.size() ? units[i] : std::string("1")});
  }
  offset_ = params.numbers("offset", std::vector<double>(names.size(), 0.0), names.size());
  offset_.resize(names.size(), 0.0);
  add_tunable({"offset", "", "", -1e300, 1e300, std::move(offset_description)}, offset_);
}

Status SourceOutput::declare(ConfigureContext& ctx) {
  ctx.declare_output(out_, "out", elements_);
  return ctx.params().ok() ? Status::ok() : Status::error("invalid parameters");
}

void SourceOutput::write_offset() noexcept {
  for (std::size_t i = 0; i < offset_.size(); ++i) out_[i] = offset_[i];
}

void SourceOutput::describe(Json& out) const {
  out["elements"] = static_cast<int>(size());
  out["offset"] = offset_;
}

bool SourceOutput::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  std::size_t group = 0, element = 0;
  if (!locate(index, value, group, element, why)) return false;
  store(group, element, value);
  return true;
}

}  // namespace lode::plugins::source
