#include "lode/sdk/params.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "params_node.hpp"

namespace lode {

namespace detail {

SourceLocation location_of(const YAML::Node& node, const std::string& file) {
  SourceLocation loc{file, 0, 0};
  if (node.IsDefined()) {
    const YAML::Mark mark = node.Mark();
    if (mark.line >= 0) {
      loc.line = mark.line + 1;
      loc.column = mark.column + 1;
    }
  }
  return loc;
}

Params make_params(const YAML::Node& map, std::string path, std::string file,
                   Diagnostics* diagnostics, const std::vector<std::string>& ignored_keys) {
  auto tree = std::make_shared<ParamsTree>();
  tree->diagnostics = diagnostics;
  tree->file = std::move(file);
  auto node = std::make_shared<ParamsNode>();
  node->node = map;
  node->path = std::move(path);
  node->tree = tree;
  for (const auto& k : ignored_keys) node->read_keys.insert(k);
  tree->maps.push_back(node);
  return Params(node);
}

void report_unread_keys(const Params& root) {
  const auto& tree = root.node()->tree;
  const auto maps = std::move(tree->maps);
  tree->maps.clear();
  for (const auto& n : maps) {
    if (!n->node.IsMap()) continue;
    std::vector<std::string> known(n->read_keys.begin(), n->read_keys.end());
    for (const auto& kv : n->node) {
      const auto key = kv.first.as<std::string>();
      if (n->read_keys.count(key)) continue;
      std::string msg = "unknown parameter '" + key + "'";
      // Suggest the closest read key: most unknown keys are typos.
      std::string best;
      std::size_t best_score = 0;
      for (const auto& k : known) {
        std::size_t common = 0;
        while (common < k.size() && common < key.size() && k[common] == key[common]) ++common;
        if (common > best_score) { best_score = common; best = k; }
      }
      if (best_score >= 3) msg += " (did you mean '" + best + "'?)";
      ++tree->errors;
      tree->diagnostics->add(location_of(kv.first, tree->file), n->path + "." + key, msg);
    }
  }
}

std::set<std::string> read_top_level_keys(const Params& root) { return root.node()->read_keys; }

std::size_t error_count(const Params& root) { return root.node()->tree->errors; }

}  // namespace detail

using detail::location_of;
using detail::ParamsNode;

namespace {

std::string describe_node(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  return "nothing";
}

/// "got '2mm'" and what to write instead: every number is in SI units, without one (the
/// field's name says which: gap_m, mass_kg, rate_hz). The prefixes and units a lab writes.
std::string number_got(const YAML::Node& n) {
  std::string got = "got " + describe_node(n);
  if (!n.IsScalar()) return got;
  const std::string& text = n.Scalar();
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || !std::isfinite(value)) return got;
  std::string unit(end);
  unit.erase(0, unit.find_first_not_of(" \t"));
  if (unit.empty()) return got;
  static const std::pair<const char*, double> kScales[] = {
      {"m", 1.0},     {"cm", 1e-2},   {"mm", 1e-3},   {"um", 1e-6},  {"µm", 1e-6},  {"nm", 1e-9},
      {"kg", 1.0},    {"g", 1e-3},    {"s", 1.0},     {"ms", 1e-3},  {"us", 1e-6},  {"µs", 1e-6},
      {"Hz", 1.0},    {"kHz", 1e3},   {"rad", 1.0},   {"mrad", 1e-3}, {"urad", 1e-6}, {"µrad", 1e-6},
      {"deg", 3.14159265358979323846 / 180.0},        {"V", 1.0},    {"mV", 1e-3},  {"uV", 1e-6},
      {"T", 1.0},     {"mT", 1e-3},   {"N", 1.0},     {"mN", 1e-3},  {"A", 1.0},    {"mA", 1e-3}};
  for (const auto& [name, scale] : kScales) {
    if (unit != name) continue;
    char si[32];
    std::snprintf(si, sizeof si, "%.6g", value * scale);
    return got + " (numbers are in SI units, written without the unit: " + si + " for " + text + ")";
  }
  return got + " (numbers are in SI units, written without the unit)";
}

}  // namespace

Params::Params() = default;
Params::~Params() = default;
Params::Params(const Params&) = default;
Params& Params::operator=(const Params&) = default;
Params::Params(std::shared_ptr<detail::ParamsNode> node) : node_(std::move(node)) {}

bool Params::has(std::string_view key) const {
  return node_->node.IsMap() && node_->node[std::string(key)].IsDefined() &&
         !node_->node[std::string(key)].IsNull();
}

SourceLocation Params::location(std::string_view key) const {
  if (!key.empty() && node_->node.IsMap()) {
    for (const auto& kv : node_->node)
      if (kv.first.as<std::string>() == key) return location_of(kv.second, node_->tree->file);
  }
  return location_of(node_->node, node_->tree->file);
}

const std::string& Params::path() const { return node_->path; }

void Params::fail(std::string_view key, std::string message) {
  ++node_->tree->errors;
  detail::ParamsTree& tree = *node_->tree;
  std::string field = node_->path + "." + std::string(key);
  if (tree.unusable_fields.count(field) > 0 || !tree.reported.emplace(field, message).second) return;
  tree.diagnostics->add(location(key), std::move(field), std::move(message));
}

namespace {

/// A field that is absent or unreadable: reported, and marked so that what a plugin says of
/// its stand-in value afterwards is not.
void fail_unusable(Params& params, std::string_view key, std::string message) {
  params.fail(key, std::move(message));
  params.node()->tree->unusable_fields.insert(params.node()->path + "." + std::string(key));
}

void fail_missing(Params& params, std::string_view key, const char* what) {
  fail_unusable(params, key, "missing required parameter '" + std::string(key) + "' (" + what + ")");
}

}  // namespace

void Params::fail(std::string message) {
  ++node_->tree->errors;
  node_->tree->diagnostics->add(location(), node_->path, std::move(message));
}

bool Params::check(bool condition, std::string_view key, std::string message) {
  if (!condition) fail(key, std::move(message));
  return condition;
}

bool Params::ok() const { return node_->tree->errors == 0; }

std::vector<std::string> Params::keys() const {
  std::vector<std::string> out;
  if (node_->node.IsMap())
    for (const auto& kv : node_->node) out.push_back(kv.first.as<std::string>());
  return out;
}

namespace {

template <typename T>
bool convert_scalar(const YAML::Node& n, T& out) {
  if (!n.IsScalar()) return false;
  try {
    out = n.as<T>();
  } catch (const YAML::Exception&) {
    return false;
  }
  if constexpr (std::is_floating_point_v<T>) return std::isfinite(out);
  return true;
}

/// A wrong element of the list `key`: counted, and reported at its own place as key[i].
void element_error(ParamsNode& node, const std::string& key, std::size_t i, const YAML::Node& element,
                   const std::string& expected) {
  ++node.tree->errors;
  node.tree->diagnostics->add(location_of(element, node.tree->file),
                              node.path + "." + key + "[" + std::to_string(i) + "]",
                              expected + ", " + number_got(element));
}

/// Every element of `list` as a T, in order; one that is not a T is reported and read as T{},
/// so the list keeps its length and the errors name every wrong element at once.
template <typename T>
std::vector<T> converted_elements(ParamsNode& node, const YAML::Node& list, const std::string& key,
                                  const std::string& expected) {
  std::vector<T> out;
  for (std::size_t i = 0; i < list.size(); ++i) {
    T v{};
    if (!convert_scalar(list[i], v)) element_error(node, key, i, list[i], expected);
    out.push_back(v);
  }
  return out;
}

}  // namespace

#define LODE_PARAM_LOOKUP(key)                    \
  const std::string k(key);                       \
  node_->read_keys.insert(k);                     \
  const YAML::Node n = node_->node.IsMap() ? node_->node[k] : YAML::Node();

double Params::number(std::string_view key) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) {
    fail_missing(*this, key, "a number");
    return 0.0;
  }
  double v = 0.0;
  if (!convert_scalar(n, v)) fail_unusable(*this, key, "expected a finite number, " + number_got(n));
  return v;
}

double Params::number(std::string_view key, double fallback) {
  if (!has(key)) {
    node_->read_keys.insert(std::string(key));
    return fallback;
  }
  return number(key);
}

std::int64_t Params::integer(std::string_view key) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) {
    fail_missing(*this, key, "an integer");
    return 0;
  }
  std::int64_t v = 0;
  if (!convert_scalar(n, v)) fail_unusable(*this, key, "expected an integer, " + number_got(n));
  return v;
}

std::int64_t Params::integer(std::string_view key, std::int64_t fallback) {
  if (!has(key)) {
    node_->read_keys.insert(std::string(key));
    return fallback;
  }
  return integer(key);
}

bool Params::flag(std::string_view key, bool fallback) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) return fallback;
  bool v = fallback;
  if (!convert_scalar(n, v)) fail_unusable(*this, key, "expected true or false, got " + describe_node(n));
  return v;
}

std::string Params::text(std::string_view key) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) {
    fail_missing(*this, key, "a text");
    return {};
  }
  if (!n.IsScalar()) {
    fail(key, "expected a text, got " + describe_node(n));
    return {};
  }
  return n.Scalar();
}

std::string Params::text(std::string_view key, std::string_view fallback) {
  if (!has(key)) {
    node_->read_keys.insert(std::string(key));
    return std::string(fallback);
  }
  return text(key);
}

std::string Params::file_path(std::string_view key, std::string_view fallback) {
  if (!has(key)) return text(key, fallback);
  const std::string value = text(key);
  const std::filesystem::path p(value);
  if (value.empty() || p.is_absolute()) return value;
  // The location's file is the pipeline file's path as loaded (or a label without a
  // directory for pipelines built from text: then relative to the working directory).
  const std::filesystem::path dir = std::filesystem::path(location(key).file).parent_path();
  return dir.empty() ? value : (dir / p).lexically_normal().string();
}

std::string Params::choice(std::string_view key, const std::vector<std::string>& allowed,
                           std::optional<std::string_view> fallback) {
  std::string v = fallback ? text(key, *fallback) : text(key);
  if (!ok() && v.empty()) return fallback ? std::string(*fallback) : allowed.front();
  if (std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    fail(key, "'" + v + "' is not one of: " + list);
    return fallback ? std::string(*fallback) : allowed.front();
  }
  return v;
}

std::vector<double> Params::numbers(std::string_view key, std::optional<std::size_t> size) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) {
    fail_missing(*this, key, "a list of numbers");
    return std::vector<double>(size.value_or(0), 0.0);
  }
  if (n.IsScalar() && size.value_or(1) == 1) {
    double v = 0.0;
    if (!convert_scalar(n, v)) fail_unusable(*this, key, "expected a finite number, " + number_got(n));
    return {v};
  }
  if (!n.IsSequence()) {
    fail(key, "expected a list of numbers, got " + describe_node(n));
    return std::vector<double>(size.value_or(0), 0.0);
  }
  std::vector<double> out = converted_elements<double>(*node_, n, k, "expected a finite number");
  if (size && out.size() != *size) {
    fail(key, "expected " + std::to_string(*size) + " numbers, got " + std::to_string(out.size()));
    out.resize(*size, 0.0);
  }
  return out;
}

std::vector<double> Params::numbers(std::string_view key, std::vector<double> fallback,
                                    std::optional<std::size_t> size) {
  if (!has(key)) {
    node_->read_keys.insert(std::string(key));
    return fallback;
  }
  return numbers(key, size);
}

std::vector<double> Params::one_or_each(std::string_view key, std::vector<double> values, std::size_t count,
                                        std::string_view each) {
  if (values.size() == 1 && count > 1) values.assign(count, values.front());
  if (values.size() != count) {
    fail(key, "expected one number or " + std::to_string(count) + " (one per " + std::string(each) + "), got " +
                  std::to_string(values.size()));
    values.resize(count, values.empty() ? 0.0 : values.back());
  }
  return values;
}

std::vector<std::int64_t> Params::integers(std::string_view key, std::vector<std::int64_t> fallback) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) return fallback;
  if (!n.IsSequence()) {
    fail(key, "expected a list of integers, got " + describe_node(n));
    return fallback;
  }
  return converted_elements<std::int64_t>(*node_, n, k, "expected an integer");
}

std::vector<std::string> Params::texts(std::string_view key, std::vector<std::string> fallback) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) return fallback;
  if (n.IsScalar()) return {n.Scalar()};
  if (!n.IsSequence()) {
    fail(key, "expected a list of texts, got " + describe_node(n));
    return fallback;
  }
  std::vector<std::string> out;
  for (std::size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsScalar()) {
      element_error(*node_, k, i, n[i], "expected a text");
      continue;
    }
    out.push_back(n[i].Scalar());
  }
  return out;
}

namespace {
Params child_of(const std::shared_ptr<ParamsNode>& parent, const YAML::Node& n, std::string path) {
  auto node = std::make_shared<ParamsNode>();
  node->node = n;
  node->path = std::move(path);
  node->tree = parent->tree;
  parent->tree->maps.push_back(node);
  return Params(node);
}
}  // namespace

std::optional<Params> Params::optional_child(std::string_view key) {
  LODE_PARAM_LOOKUP(key);
  if (!n.IsDefined() || n.IsNull()) return std::nullopt;
  if (!n.IsMap()) {
    fail(key, "expected a map, got " + describe_node(n));
    return std::nullopt;
  }
  return child_of(node_, n, node_->path + "." + k);
}

Params Params::child(std::string_view key) {
  auto c = optional_child(key);
  if (c) return *c;
  if (ok() || !has(key)) {
    if (!has(key)) fail_missing(*this, key, "a map");
  }
  return child_of(node_, YAML::Node(YAML::NodeType::Map), node_->path + "." + std::string(key));
}

std::vector<Params> Params::items(std::string_view key) {
  LODE_PARAM_LOOKUP(key);
  std::vector<Params> out;
  if (!n.IsDefined() || n.IsNull()) {
    fail_missing(*this, key, "a list of maps");
    return out;
  }
  if (!n.IsSequence() || n.size() == 0) {
    fail(key, "expected a non-empty list of maps, got " + describe_node(n));
    return out;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const std::string p = node_->path + "." + k + "[" + std::to_string(i) + "]";
    if (!n[i].IsMap()) {
      ++node_->tree->errors;
      node_->tree->diagnostics->add(location_of(n[i], node_->tree->file), p,
                                    "expected a map, got " + describe_node(n[i]));
      continue;
    }
    out.push_back(child_of(node_, n[i], p));
  }
  return out;
}

}  // namespace lode
