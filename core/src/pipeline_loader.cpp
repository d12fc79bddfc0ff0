// Loading a pipeline: the YAML file becomes blocks, models and sections, every problem located
// by file, line and column; nothing is returned half-configured.
#include "lode/sdk/clock.hpp"
#include "lode/config_file.hpp"
#include "lode/pipeline.hpp"

#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstring>
#include <fstream>
#include <limits>
#include <deque>
#include <map>
#include <set>
#include <sstream>

#include "lode/telemetry.hpp"
#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

namespace {

constexpr const char* kTopLevelKeys[] = {"pipeline", "rate_hz",   "duration_s", "realtime", "models", "blocks",
                                         "monitor",  "telemetry", "health",     "record",   "envelope"};

}  // namespace

std::string pipeline_name_problem(const std::string& name) {
  constexpr std::size_t kMaxLength = 64;
  if (name.empty()) return "the pipeline name is empty";
  if (name.size() > kMaxLength)
    return "the pipeline name is " + std::to_string(name.size()) + " characters long; at most " +
           std::to_string(kMaxLength) + " are allowed";
  if (name.front() == '.' || name.front() == '-')
    return "the pipeline name '" + name + "' starts with '" + name.front() + "'";
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.';
    if (!ok)
      return "the pipeline name '" + name + "' may hold only letters, digits, '_', '-' and '.'";
  }
  return {};
}

std::unique_ptr<Pipeline> Pipeline::load_file(const std::string& path, PluginRegistry& registry,
                                              Diagnostics& diagnostics) {
  const auto text = read_config_file(path, diagnostics);
  if (!text) return nullptr;
  return load_text(*text, path, registry, diagnostics);
}

std::unique_ptr<Pipeline> Pipeline::load_text(const std::string& yaml, const std::string& label,
                                              PluginRegistry& registry, Diagnostics& diagnostics,
                                              const std::vector<std::pair<std::string, Elements>>& feeds) {
  std::unique_ptr<Pipeline> p(new Pipeline());
  Impl& im = *p->impl_;
  im.file = label;
  im.source_text = yaml;
  im.registry = &registry;
  im.diag = &diagnostics;
  if (yaml.size() > kMaxConfigFileBytes) {
    diagnostics.add({label, 0, 0}, "", "is larger than " + std::to_string(kMaxConfigFileBytes) +
                                           " bytes, the most a configuration may be");
    return nullptr;
  }
  const auto parsed = detail::parse_config_yaml(yaml, label, diagnostics);
  if (!parsed) return nullptr;
  const YAML::Node& root = *parsed;
  if (!feeds.empty()) {
    auto feed = std::make_unique<BlockEntry>();
    feed->name = "feed";
    feed->configured = true;
    for (const auto& [port, elements] : feeds)
      feed->outputs.push_back({port, elements, &im.feed_ports.emplace_back(), 0});
    im.blocks.push_back(std::move(feed));
  }
  if (!im.parse_top(root)) return nullptr;
  const auto order = im.order_blocks();
  // Every block derives its discrete-time constants from the rate: without a valid one, what
  // they would refuse is noise (a controller's "matched gain is not finite" at 0 Hz).
  if (im.rate_hz > 0)
    for (auto* b : order) im.configure_block(*b);
  im.resolve_inputs();
  im.check_shadows(order);
  if (!diagnostics.empty()) return nullptr;
  im.allocate_and_bind();
  im.build_ops(order);
  im.build_families();
  im.parse_monitor(root["monitor"]);
  im.parse_telemetry(root["telemetry"]);
  im.parse_health(root["health"]);
  im.refresh_watched();
  im.parse_envelope(root["envelope"]);
  if (!diagnostics.empty()) return nullptr;
  return p;
}

// --------------------------------------------------------------------------------------

bool Pipeline::Impl::parse_top(const YAML::Node& root) {
  if (!root.IsMap()) {
    error(detail::location_of(root, file), "", "a pipeline file must be a YAML map");
    return false;
  }
  std::set<std::string> allowed(std::begin(kTopLevelKeys), std::end(kTopLevelKeys));
  std::string allowed_list;  // in the order a pipeline file usually has them
  for (const char* k : kTopLevelKeys) allowed_list += (allowed_list.empty() ? "" : ", ") + std::string(k);
  for (const auto& kv : root) {
    const auto key = kv.first.as<std::string>();
    if (!allowed.count(key))
      error(detail::location_of(kv.first, file), key, "unknown top-level key '" + key + "' (allowed: " + allowed_list + ")");
  }
  if (!root["pipeline"] || !root["pipeline"].IsScalar())
    error(detail::location_of(root, file), "pipeline", "missing pipeline name (pipeline: <name>)");
  else if (const std::string why = pipeline_name_problem(root["pipeline"].Scalar()); !why.empty())
    error(detail::location_of(root["pipeline"], file), "pipeline", why);
  else
    name = root["pipeline"].Scalar();

  const YAML::Node rate = root["rate_hz"];
  if (!rate) {
    error(detail::location_of(root, file), "rate_hz", "missing rate_hz (the cycle rate in Hz)");
  } else {
    double r = 0;
    bool ok = rate.IsScalar();
    if (ok) {
      try { r = rate.as<double>(); } catch (const YAML::Exception&) { ok = false; }
    }
    if (!ok || !std::isfinite(r) || r <= 0 || r > 100000)
      error(detail::location_of(rate, file), "rate_hz",
            "rate_hz must be a number in (0, 100000], got '" + (rate.IsScalar() ? rate.Scalar() : "?") +
                "' (the blocks are checked once it is valid: their constants depend on it)");
    else
      rate_hz = r;
  }
  if (const auto d = root["duration_s"]) {
    double v = -1;
    try { v = d.as<double>(); } catch (const YAML::Exception&) {}
    if (!(v > 0) || !std::isfinite(v))
      error(detail::location_of(d, file), "duration_s", "duration_s must be a positive number");
    else
      duration_s = v;
  }
  // 0 cycles means "until stopped" to the scheduler: a duration shorter than one cycle must be
  // refused, not rounded to it.
  if (duration_s && rate_hz > 0 && std::llround(*duration_s * rate_hz) < 1)
    error(detail::location_of(root["duration_s"], file), "duration_s",
          "duration_s " + root["duration_s"].Scalar() + " is shorter than one cycle at rate_hz " +
              root["rate_hz"].Scalar());
  if (root["realtime"]) parse_realtime(root["realtime"]);
  if (root["record"]) parse_record(root["record"]);
  if (root["models"]) parse_models(root["models"]);
  const YAML::Node blocks_node = root["blocks"];
  if (!blocks_node || !blocks_node.IsMap() || blocks_node.size() == 0) {
    error(detail::location_of(blocks_node ? blocks_node : root, file), "blocks",
          "missing or empty `blocks:` map");
    return false;
  }
  parse_blocks(blocks_node);
  return true;
}

void Pipeline::Impl::parse_models(const YAML::Node& models_node) {
  if (!models_node.IsMap()) {
    error(detail::location_of(models_node, file), "models", "expected a map of named models");
    return;
  }
  for (const auto& kv : models_node) {
    ModelSpec spec;
    spec.name = kv.first.as<std::string>();
    spec.node = kv.second;
    spec.where = detail::location_of(kv.first, file);
    const std::string path = "models." + spec.name;
    if (!kv.second.IsMap() || !kv.second["plugin"] || !kv.second["plugin"].IsScalar()) {
      error(spec.where, path, "a model needs `plugin: <name>` (e.g. sensor.halbach_hall)");
    } else {
      auto loaded = registry->find(kv.second["plugin"].Scalar());
      if (!loaded) {
        error(detail::location_of(kv.second["plugin"], file), path + ".plugin", loaded.error());
      } else if (creates_block(loaded->descriptor->kind)) {
        error(detail::location_of(kv.second["plugin"], file), path + ".plugin",
              std::string("plugin ") + loaded->descriptor->name + " is a block, not a model (its kind is " +
                  to_string(loaded->descriptor->kind) + "; models are plant or sensor): declare it under `blocks:`");
      } else {
        spec.plugin = *loaded;
      }
    }
    models[spec.name] = std::move(spec);
  }
}

void Pipeline::Impl::parse_blocks(const YAML::Node& blocks_node) {
  for (const auto& kv : blocks_node) {
    auto e = std::make_unique<BlockEntry>();
    e->name = kv.first.as<std::string>();
    e->node = kv.second;
    e->where = detail::location_of(kv.first, file);
    const std::string path = "blocks." + e->name;
    if (e->name.find('.') != std::string::npos)
      error(e->where, path, "block names may not contain '.' (it separates block and port)");
    if (!kv.second.IsMap()) {
      error(e->where, path, "a block must be a map with at least `plugin: <name>`");
      blocks.push_back(std::move(e));
      continue;
    }
    const YAML::Node plugin = kv.second["plugin"];
    if (!plugin || !plugin.IsScalar()) {
      error(e->where, path + ".plugin", "missing `plugin: <name>` (run `lode plugins` for the list)");
    } else {
      e->plugin_name = plugin.Scalar();
      auto loaded = registry->find(e->plugin_name);
      if (!loaded) {
        error(detail::location_of(plugin, file), path + ".plugin", loaded.error());
      } else if (!creates_block(loaded->descriptor->kind)) {
        error(detail::location_of(plugin, file), path + ".plugin",
              std::string("plugin ") + loaded->descriptor->name + " is a " +
                  to_string(loaded->descriptor->kind) +
                  " model: declare it under `models:` and name it from a block");
      } else {
        e->plugin = *loaded;
      }
    }
    if (const YAML::Node shadow = kv.second["shadow_of"]) {
      e->shadow_where = detail::location_of(shadow, file);
      if (!shadow.IsScalar() || shadow.Scalar().empty())
        error(e->shadow_where, path + ".shadow_of", "expected the name of the block this one shadows");
      else
        e->shadow_of = shadow.Scalar();
    }
    if (const YAML::Node dec = kv.second["shadow_decimation"]) {
      long long n = 0;
      try { n = dec.as<long long>(); } catch (const YAML::Exception&) { n = 0; }
      if (!kv.second["shadow_of"])
        error(detail::location_of(dec, file), path + ".shadow_decimation", "only a shadow (shadow_of: ...) can be decimated");
      else if (n < 1 || n > 100000)
        error(detail::location_of(dec, file), path + ".shadow_decimation",
              "must be an integer in 1..100000 (the shadow steps every n-th cycle, at rate_hz / n)");
      else
        e->shadow_decimation = static_cast<std::uint32_t>(n);
    }
    if (const YAML::Node inputs = kv.second["inputs"]) parse_wiring(inputs, path, *e);
    blocks.push_back(std::move(e));
  }
  // Sources must exist (ports are checked once everything is configured).
  for (auto& b : blocks)
    for (auto& w : b->wiring) {
      const BlockEntry* src = find_block(w.src_block);
      if (!src)
        error(w.where, "blocks." + b->name + ".inputs." + w.input,
              "no block named '" + w.src_block + "'");
      else if (!src->shadow_of.empty())
        error(w.where, "blocks." + b->name + ".inputs." + w.input,
              "'" + w.src_block + "' is a shadow of '" + src->shadow_of +
                  "': its outputs can be watched (monitor, telemetry, recording) but not wired; "
                  "promote it (lode swap --promote " + w.src_block + ") to feed the pipeline");
    }
  // A shadow runs on its primary's inputs unless it names its own.
  for (auto& b : blocks) {
    if (b->shadow_of.empty()) continue;
    const std::string path = "blocks." + b->name + ".shadow_of";
    const BlockEntry* primary = find_block(b->shadow_of);
    if (!primary) {
      error(b->shadow_where, path, "no block named '" + b->shadow_of + "'");
    } else if (primary == b.get()) {
      error(b->shadow_where, path, "a block cannot shadow itself");
    } else if (!primary->shadow_of.empty()) {
      error(b->shadow_where, path, "'" + b->shadow_of + "' is itself a shadow (of '" + primary->shadow_of +
                                       "'); shadow the primary instead");
    } else if (primary->is_io() || b->is_io()) {
      error(b->shadow_where, path, "io blocks own hardware and cannot be shadowed or shadows");
    } else if (b->wiring.empty()) {
      b->wiring = primary->wiring;
    }
  }
}

void Pipeline::Impl::parse_wiring(const YAML::Node& inputs, const std::string& path, BlockEntry& e) {
  if (!inputs.IsMap()) {
    error(detail::location_of(inputs, file), path + ".inputs", "expected a map `input_name: block.port`");
    return;
  }
  for (const auto& in : inputs) {
    InputWiring w;
    w.input = in.first.IsScalar() ? in.first.Scalar() : std::string("?");
    w.where = detail::location_of(in.second, file);
    if (!in.second.IsScalar()) {
      error(w.where, path + ".inputs." + w.input, "expected `block.port`");
      continue;
    }
    w.source = in.second.Scalar();
    const auto dot = w.source.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == w.source.size()) {
      error(w.where, path + ".inputs." + w.input, "'" + w.source + "' is not a `block.port` reference");
      continue;
    }
    w.src_block = w.source.substr(0, dot);
    w.src_port = w.source.substr(dot + 1);
    e.wiring.push_back(std::move(w));
  }
}

}  // namespace lode
