#include "lode/pipeline.hpp"

#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <deque>
#include <map>
#include <set>
#include <sstream>

#include "lode/telemetry.hpp"
#include "lode/units.hpp"
#include "params_node.hpp"
#include "port_binder.hpp"

namespace lode {

namespace {

constexpr const char* kTopLevelKeys[] = {"pipeline", "rate_hz", "duration_s", "realtime",
                                         "models",   "blocks",  "monitor",    "telemetry"};

std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct DeclaredOutput {
  std::string name;
  Elements elements;
  OutputPort* port = nullptr;
  std::size_t offset = 0;  // into the arena
};

struct DeclaredInput {
  std::string name;
  Elements expected;
  bool required = true;
  InputPort* port = nullptr;
};

struct InputWiring {
  std::string input;       // input name on this block
  std::string source;      // "block.port" as written
  std::string src_block;
  std::string src_port;
  SourceLocation where;    // of the value
};

struct ModelSpec {
  std::string name;
  LoadedPlugin plugin;
  YAML::Node node;
  SourceLocation where;
};

struct BlockEntry {
  std::string name;
  std::string plugin_name;
  LoadedPlugin plugin;
  YAML::Node node;
  SourceLocation where;
  std::vector<InputWiring> wiring;
  std::unique_ptr<Block> block;
  std::vector<DeclaredOutput> outputs;
  std::vector<DeclaredInput> inputs;
  bool configured = false;
  bool is_io() const { return plugin.descriptor && plugin.descriptor->kind == PluginKind::io; }
  const DeclaredOutput* output(const std::string& port) const {
    for (const auto& o : outputs)
      if (o.name == port) return &o;
    return nullptr;
  }
};

std::string element_list(const Elements& e) {
  std::string s = "[";
  for (std::size_t i = 0; i < e.size(); ++i)
    s += (i ? ", " : "") + e[i].name + (e[i].unit.empty() ? "" : " " + e[i].unit);
  return s + "]";
}

Json elements_json(const Elements& e) {
  Json a = Json::array();
  for (const auto& el : e) {
    Json j = Json::object();
    j["name"] = el.name;
    j["unit"] = el.unit;
    a.push(std::move(j));
  }
  return a;
}

/// YAML node -> Json (for echoing resolved parameters in describe()).
Json to_json(const YAML::Node& n) {
  if (n.IsMap()) {
    Json j = Json::object();
    for (const auto& kv : n) j[kv.first.as<std::string>()] = to_json(kv.second);
    return j;
  }
  if (n.IsSequence()) {
    Json j = Json::array();
    for (const auto& e : n) j.push(to_json(e));
    return j;
  }
  if (n.IsScalar()) {
    const auto& s = n.Scalar();
    if (s == "true" || s == "false") return Json(s == "true");
    char* end = nullptr;
    const double d = std::strtod(s.c_str(), &end);
    if (end && *end == '\0' && !s.empty()) return Json(d);
    return Json(s);
  }
  return Json();
}

/// yaml-cpp 0.7 silently keeps the last of duplicate keys: find them ourselves.
void check_duplicate_keys(const YAML::Node& n, const std::string& path, const std::string& file,
                          Diagnostics& diag) {
  if (n.IsMap()) {
    std::set<std::string> seen;
    for (const auto& kv : n) {
      const auto key = kv.first.as<std::string>();
      if (!seen.insert(key).second)
        diag.add(detail::location_of(kv.first, file), path.empty() ? key : path + "." + key,
                 "duplicate key '" + key + "' (the earlier value would be silently ignored)");
      check_duplicate_keys(kv.second, path.empty() ? key : path + "." + key, file, diag);
    }
  } else if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i)
      check_duplicate_keys(n[i], path + "[" + std::to_string(i) + "]", file, diag);
  }
}

}  // namespace

struct Pipeline::Impl {
  std::string name;
  std::string file;
  double rate_hz = 0.0;
  std::optional<double> duration_s;
  RealtimeSettings realtime;
  MonitorSpec monitor;
  TelemetrySpec telemetry;
  std::string source_text;
  std::map<std::string, ModelSpec> models;
  std::vector<std::unique_ptr<BlockEntry>> blocks;  // file order
  std::vector<double> arena;
  std::vector<Op> ops;
  bool active = false;

  std::deque<OutputPort> feed_ports;  // storage handles of the test pseudo-block "feed"
  PluginRegistry* registry = nullptr;
  Diagnostics* diag = nullptr;

  BlockEntry* find_block(const std::string& n) {
    for (auto& b : blocks)
      if (b->name == n) return b.get();
    return nullptr;
  }
  const BlockEntry* find_block(const std::string& n) const {
    for (const auto& b : blocks)
      if (b->name == n) return b.get();
    return nullptr;
  }

  void error(const SourceLocation& where, const std::string& field, const std::string& msg) {
    diag->add(where, field, msg);
  }

  bool parse_top(const YAML::Node& root);
  void parse_realtime(const YAML::Node& rt);
  void parse_models(const YAML::Node& models_node);
  void parse_blocks(const YAML::Node& blocks_node);
  std::vector<BlockEntry*> order_blocks();
  void configure_block(BlockEntry& entry);
  void check_documented(const LoadedPlugin& plugin, const Params& params, const std::string& path);
  void resolve_inputs();
  void allocate_and_bind();
  void build_ops(const std::vector<BlockEntry*>& order);
  void parse_monitor(const YAML::Node& m);
  void parse_telemetry(const YAML::Node& t);
  std::optional<SignalRef> signal(const std::string& ref) const;

  template <typename M>
  std::unique_ptr<M> make_model(Params& block_params, std::string_view key, PluginKind kind) {
    const std::string model_name = block_params.text(key);
    if (model_name.empty()) return nullptr;
    return make_model_named<M>(block_params, key, model_name, kind);
  }
  template <typename M>
  std::unique_ptr<M> make_model_named(Params& block_params, std::string_view key,
                                      const std::string& model_name, PluginKind kind);
};

// --------------------------------------------------------------------------------------
// The context each block's configure() sees.
class LoaderContext final : public ConfigureContext {
 public:
  LoaderContext(Pipeline::Impl& p, BlockEntry& e, Params& params)
      : p_(p), e_(e), params_(params) {}

  Params& params() override { return params_; }
  [[nodiscard]] const std::string& block_name() const override { return e_.name; }
  [[nodiscard]] double rate_hz() const override { return p_.rate_hz; }

  void declare_output(OutputPort& port, const std::string& name, Elements elements) override {
    for (const auto& o : e_.outputs)
      if (o.name == name) {
        params_.fail("plugin " + e_.plugin_name + " declared output '" + name + "' twice");
        return;
      }
    if (elements.empty()) {
      params_.fail("plugin " + e_.plugin_name + " declared output '" + name + "' with no elements");
      return;
    }
    e_.outputs.push_back({name, std::move(elements), &port, 0});
  }

  void declare_input(InputPort& port, const std::string& name, Elements expected,
                     bool required) override {
    e_.inputs.push_back({name, std::move(expected), required, &port});
  }

  [[nodiscard]] const Elements* input_source(const std::string& name) const override {
    for (const auto& w : e_.wiring) {
      if (w.input != name) continue;
      const BlockEntry* src = p_.find_block(w.src_block);
      if (!src || !src->configured) return nullptr;
      const DeclaredOutput* o = src->output(w.src_port);
      return o ? &o->elements : nullptr;
    }
    return nullptr;
  }

  std::unique_ptr<PlantModel> plant_model(std::string_view key) override {
    return p_.make_model<PlantModel>(params_, key, PluginKind::plant);
  }
  std::unique_ptr<MeasurementModel> measurement_model(std::string_view key) override {
    return p_.make_model<MeasurementModel>(params_, key, PluginKind::sensor);
  }
  std::unique_ptr<ProcessModel> process_model(std::string_view key) override {
    return p_.make_model<ProcessModel>(params_, key, PluginKind::process);
  }
  std::vector<std::unique_ptr<MeasurementModel>> measurement_models(std::string_view key) override {
    std::vector<std::unique_ptr<MeasurementModel>> out;
    for (const auto& name : params_.texts(key, {})) {
      auto m = p_.make_model_named<MeasurementModel>(params_, key, name, PluginKind::sensor);
      if (m) out.push_back(std::move(m));
    }
    if (!params_.has(key)) params_.fail(key, "missing required parameter (a list of model names)");
    return out;
  }

 private:
  Pipeline::Impl& p_;
  BlockEntry& e_;
  Params& params_;
};

template <typename M>
std::unique_ptr<M> Pipeline::Impl::make_model_named(Params& block_params, std::string_view key,
                                                    const std::string& model_name,
                                                    PluginKind kind) {
  auto it = models.find(model_name);
  if (it == models.end()) {
    std::string known;
    for (const auto& [n, _] : models) known += (known.empty() ? "" : ", ") + n;
    block_params.fail(key, "no model named '" + model_name + "' in `models:`" +
                               (known.empty() ? std::string(" (there is no models: section)")
                                              : " (models: " + known + ")"));
    return nullptr;
  }
  ModelSpec& spec = it->second;
  if (!spec.plugin.descriptor) return nullptr;  // its plugin failed to load: already reported
  // The interface decides, not the declared kind: a plant plugin may also be a process model.
  std::unique_ptr<Component> made(spec.plugin.descriptor->create());
  auto* typed = dynamic_cast<M*>(made.get());
  if (!typed) {
    block_params.fail(key, "model '" + model_name + "' is a " +
                               to_string(spec.plugin.descriptor->kind) + " (" +
                               spec.plugin.descriptor->name + "), this parameter needs a " +
                               to_string(kind) + " model");
    return nullptr;
  }
  made.release();
  std::unique_ptr<M> model(typed);
  Params mp = detail::make_params(spec.node, "models." + model_name, file, diag, {"plugin"});
  Status st;
  try {
    st = model->configure(mp);
  } catch (const std::exception& ex) {
    st = Status::error(std::string("configure() threw: ") + ex.what());
  }
  detail::report_unread_keys(mp);
  check_documented(spec.plugin, mp, "models." + model_name);
  if (!st || !mp.ok()) {
    if (mp.ok()) error(spec.where, "models." + model_name, st.message());
    return nullptr;
  }
  return model;
}

void Pipeline::Impl::check_documented(const LoadedPlugin& plugin, const Params& params,
                                      const std::string& path) {
  std::set<std::string> documented{"plugin", "inputs"};
  for (std::size_t i = 0; i < plugin.descriptor->param_count; ++i)
    documented.insert(plugin.descriptor->params[i].name);
  for (const auto& k : detail::read_top_level_keys(params))
    if (!documented.count(k))
      error(params.location(), path + "." + k,
            std::string("plugin ") + plugin.descriptor->name + " reads parameter '" + k +
                "' that its descriptor does not document (a bug in the plugin)");
}

// --------------------------------------------------------------------------------------

bool Pipeline::Impl::parse_top(const YAML::Node& root) {
  if (!root.IsMap()) {
    error(detail::location_of(root, file), "", "a pipeline file must be a YAML map");
    return false;
  }
  std::set<std::string> allowed(std::begin(kTopLevelKeys), std::end(kTopLevelKeys));
  for (const auto& kv : root) {
    const auto key = kv.first.as<std::string>();
    if (!allowed.count(key))
      error(detail::location_of(kv.first, file), key,
            "unknown top-level key '" + key +
                "' (allowed: pipeline, rate_hz, duration_s, realtime, models, blocks, monitor, telemetry)");
  }
  if (!root["pipeline"] || !root["pipeline"].IsScalar())
    error(detail::location_of(root, file), "pipeline", "missing pipeline name (pipeline: <name>)");
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
            "rate_hz must be a number in (0, 100000], got '" + (rate.IsScalar() ? rate.Scalar() : "?") + "'");
    else
      rate_hz = r;
  }
  if (const auto d = root["duration_s"]) {
    double v = -1;
    try { v = d.as<double>(); } catch (const YAML::Exception&) {}
    if (!(v > 0)) error(detail::location_of(d, file), "duration_s", "duration_s must be a positive number");
    else duration_s = v;
  }
  if (root["realtime"]) parse_realtime(root["realtime"]);
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

void Pipeline::Impl::parse_realtime(const YAML::Node& rt) {
  if (!rt.IsMap()) {
    error(detail::location_of(rt, file), "realtime", "expected a map");
    return;
  }
  Params p = detail::make_params(rt, "realtime", file, diag);
  realtime.priority = static_cast<int>(p.integer("priority", 0));
  p.check(realtime.priority >= 0 && realtime.priority <= 99, "priority",
          "SCHED_FIFO priority must be 0 (none) or 1..99, got " + std::to_string(realtime.priority));
  realtime.cpu = static_cast<int>(p.integer("cpu", -1));
  p.check(realtime.cpu >= -1 && realtime.cpu < 1024, "cpu", "cpu must be -1 (any) or a CPU index");
  realtime.lock_memory = p.flag("lock_memory", false);
  const auto policy = p.choice("overrun_policy", {"skip", "catch_up", "stop"}, "skip");
  realtime.overrun_policy = policy == "stop"       ? OverrunPolicy::stop
                            : policy == "catch_up" ? OverrunPolicy::catch_up
                                                   : OverrunPolicy::skip;
  const auto max_over = p.integer("max_overruns", 0);
  p.check(max_over >= 0, "max_overruns", "must be >= 0");
  realtime.max_overruns = static_cast<std::uint64_t>(std::max<std::int64_t>(0, max_over));
  detail::report_unread_keys(p);
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
      } else if (loaded->descriptor->kind != PluginKind::plant &&
                 loaded->descriptor->kind != PluginKind::sensor &&
                 loaded->descriptor->kind != PluginKind::process) {
        error(detail::location_of(kv.second["plugin"], file), path + ".plugin",
              std::string("plugin ") + loaded->descriptor->name + " is a " +
                  to_string(loaded->descriptor->kind) + ", not a model (plant, sensor or process)");
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
      } else if (loaded->descriptor->kind != PluginKind::block &&
                 loaded->descriptor->kind != PluginKind::io) {
        error(detail::location_of(plugin, file), path + ".plugin",
              std::string("plugin ") + loaded->descriptor->name + " is a " +
                  to_string(loaded->descriptor->kind) +
                  " model: declare it under `models:` and name it from a block");
      } else {
        e->plugin = *loaded;
      }
    }
    if (const YAML::Node inputs = kv.second["inputs"]) {
      if (!inputs.IsMap()) {
        error(detail::location_of(inputs, file), path + ".inputs",
              "expected a map `input_name: block.port`");
      } else {
        for (const auto& in : inputs) {
          InputWiring w;
          w.input = in.first.as<std::string>();
          w.where = detail::location_of(in.second, file);
          if (!in.second.IsScalar()) {
            error(w.where, path + ".inputs." + w.input, "expected `block.port`");
            continue;
          }
          w.source = in.second.Scalar();
          const auto dot = w.source.find('.');
          if (dot == std::string::npos || dot == 0 || dot + 1 == w.source.size()) {
            error(w.where, path + ".inputs." + w.input,
                  "'" + w.source + "' is not a `block.port` reference");
            continue;
          }
          w.src_block = w.source.substr(0, dot);
          w.src_port = w.source.substr(dot + 1);
          e->wiring.push_back(std::move(w));
        }
      }
    }
    blocks.push_back(std::move(e));
  }
  // Sources must exist (ports are checked once everything is configured).
  for (auto& b : blocks)
    for (auto& w : b->wiring)
      if (!find_block(w.src_block))
        error(w.where, "blocks." + b->name + ".inputs." + w.input,
              "no block named '" + w.src_block + "'");
}

std::vector<BlockEntry*> Pipeline::Impl::order_blocks() {
  // io blocks are sources (read phase) and sinks (write phase): edges into them never
  // constrain the order, so feedback through the plant is not a cycle (DESIGN.md §2).
  std::vector<BlockEntry*> io, rest;
  std::vector<BlockEntry*> feeds;
  for (auto& b : blocks) (!b->plugin.descriptor && b->configured ? feeds : b->is_io() ? io : rest).push_back(b.get());
  std::map<BlockEntry*, std::set<BlockEntry*>> deps;  // block -> non-io blocks it reads
  for (auto* b : rest) {
    deps[b];
    for (const auto& w : b->wiring) {
      BlockEntry* src = find_block(w.src_block);
      if (src && !src->is_io() && src->block == nullptr && src->configured) continue;  // feed
      if (src && !src->is_io() && src != b) deps[b].insert(src);
      if (src == b) error(w.where, "blocks." + b->name + ".inputs." + w.input,
                          "block '" + b->name + "' reads its own output: algebraic loop");
    }
  }
  std::vector<BlockEntry*> order = io;
  std::set<BlockEntry*> placed(io.begin(), io.end());
  placed.insert(feeds.begin(), feeds.end());
  bool progress = true;
  while (progress) {
    progress = false;
    for (auto* b : rest) {  // file order breaks ties: the order a person wrote is kept
      if (placed.count(b)) continue;
      bool ready = true;
      for (auto* d : deps[b]) ready = ready && placed.count(d);
      if (ready) {
        order.push_back(b);
        placed.insert(b);
        progress = true;
      }
    }
  }
  if (order.size() + feeds.size() != blocks.size()) {
    std::string names;
    BlockEntry* first = nullptr;
    for (auto* b : rest)
      if (!placed.count(b)) {
        names += (names.empty() ? "" : ", ") + b->name;
        if (!first) first = b;
      }
    SourceLocation where = first->where;
    for (const auto& w : first->wiring) {
      BlockEntry* src = find_block(w.src_block);
      if (src && !placed.count(src) && !src->is_io()) { where = w.where; break; }
    }
    error(where, "blocks", "cycle among blocks: " + names +
                               " (only io blocks may close a loop: they read at the start of "
                               "the cycle and write at its end)");
    for (auto* b : rest)
      if (!placed.count(b)) order.push_back(b);  // still configure them to find more problems
  }
  return order;
}

void Pipeline::Impl::configure_block(BlockEntry& e) {
  if (!e.plugin.descriptor) return;
  const std::string path = "blocks." + e.name;
  std::unique_ptr<Component> made(e.plugin.descriptor->create());
  auto* block = dynamic_cast<Block*>(made.get());
  if (!block) {
    error(e.where, path, std::string("plugin ") + e.plugin.descriptor->name + " did not create a Block");
    return;
  }
  made.release();
  e.block.reset(block);
  Params params = detail::make_params(e.node, path, file, diag, {"plugin", "inputs"});
  LoaderContext ctx(*this, e, params);
  Status st;
  try {
    st = e.block->configure(ctx);
  } catch (const std::exception& ex) {
    st = Status::error(std::string("configure() threw: ") + ex.what());
  }
  detail::report_unread_keys(params);
  check_documented(e.plugin, params, path);
  if (!st && params.ok()) error(e.where, path, st.message());
  e.configured = true;
}

void Pipeline::Impl::resolve_inputs() {
  for (auto& b : blocks) {
    if (!b->block) continue;
    const std::string path = "blocks." + b->name + ".inputs";
    // Every wired input must be declared, every required one wired.
    for (const auto& w : b->wiring) {
      const auto it = std::find_if(b->inputs.begin(), b->inputs.end(),
                                   [&](const DeclaredInput& d) { return d.name == w.input; });
      if (it == b->inputs.end()) {
        std::string names;
        for (const auto& d : b->inputs) names += (names.empty() ? "" : ", ") + d.name;
        error(w.where, path + "." + w.input,
              "plugin " + b->plugin_name + " has no input '" + w.input + "'" +
                  (names.empty() ? " (it has no inputs)" : " (inputs: " + names + ")"));
        continue;
      }
      const BlockEntry* src = find_block(w.src_block);
      if (!src || !src->configured) continue;  // reported already (a feed has no block but is configured)
      const DeclaredOutput* out = src->output(w.src_port);
      if (!out) {
        std::string names;
        for (const auto& o : src->outputs) names += (names.empty() ? "" : ", ") + o.name;
        error(w.where, path + "." + w.input,
              "block '" + src->name + "' has no output '" + w.src_port + "' (outputs: " + names + ")");
        continue;
      }
      const Elements& want = it->expected;
      if (!want.empty() && want.size() != out->elements.size()) {
        error(w.where, path + "." + w.input,
              "size mismatch: input '" + w.input + "' of " + b->name + " takes " +
                  std::to_string(want.size()) + " elements " + element_list(want) + ", " +
                  w.source + " has " + std::to_string(out->elements.size()) + " " +
                  element_list(out->elements));
        continue;
      }
      for (std::size_t i = 0; i < want.size(); ++i) {
        if (!units_compatible(out->elements[i].unit, want[i].unit)) {
          error(w.where, path + "." + w.input,
                "unit mismatch at element " + std::to_string(i) + ": " + w.source + "." +
                    out->elements[i].name + " is in '" + out->elements[i].unit + "', input '" +
                    w.input + "." + want[i].name + "' expects '" + want[i].unit + "'");
          break;
        }
      }
    }
    for (const auto& d : b->inputs) {
      const bool wired = std::any_of(b->wiring.begin(), b->wiring.end(),
                                     [&](const InputWiring& w) { return w.input == d.name; });
      if (d.required && !wired)
        error(b->where, path + "." + d.name,
              "required input '" + d.name + "' is not connected (add `inputs: {" + d.name +
                  ": block.port}`)" + (d.expected.empty() ? "" : ", expects " + element_list(d.expected)));
    }
  }
}

void Pipeline::Impl::allocate_and_bind() {
  std::size_t total = 0;
  for (auto& b : blocks)
    for (auto& o : b->outputs) {
      o.offset = total;
      total += o.elements.size();
    }
  // One allocation for every signal of the pipeline; never resized afterwards, so the
  // pointers handed to the blocks stay valid for the pipeline's lifetime.
  arena.assign(total, 0.0);
  for (auto& b : blocks)
    for (auto& o : b->outputs) PortBinder::bind(*o.port, arena.data() + o.offset, o.elements.size());
  for (auto& b : blocks)
    for (auto& d : b->inputs)
      for (const auto& w : b->wiring) {
        if (w.input != d.name) continue;
        const BlockEntry* src = find_block(w.src_block);
        const DeclaredOutput* out = src ? src->output(w.src_port) : nullptr;
        if (out) PortBinder::bind(*d.port, arena.data() + out->offset, out->elements.size());
      }
}

void Pipeline::Impl::build_ops(const std::vector<BlockEntry*>& order) {
  for (auto* b : order) {
    if (!b->block) continue;
    Op op;
    op.block = b->block.get();
    op.label = b->is_io() ? b->name + ".read" : b->name;
    op.exec_time = std::make_unique<Histogram>();
    ops.push_back(std::move(op));
  }
  for (auto* b : order) {
    if (!b->block || !b->is_io()) continue;
    Op op;
    op.block = b->block.get();
    op.label = b->name + ".write";
    op.write_phase = true;
    op.exec_time = std::make_unique<Histogram>();
    ops.push_back(std::move(op));
  }
}

std::optional<SignalRef> Pipeline::Impl::signal(const std::string& ref) const {
  const auto dot = ref.find('.');
  if (dot == std::string::npos) return std::nullopt;
  const BlockEntry* b = find_block(ref.substr(0, dot));
  if (!b) return std::nullopt;
  const DeclaredOutput* o = b->output(ref.substr(dot + 1));
  if (!o || !o->port || !o->port->bound()) return std::nullopt;
  return SignalRef{b->name, o->name, o->port->data(), &o->elements};
}

void Pipeline::Impl::parse_monitor(const YAML::Node& m) {
  if (!m) return;
  if (!m.IsMap()) {
    error(detail::location_of(m, file), "monitor", "expected a map");
    return;
  }
  Params p = detail::make_params(m, "monitor", file, diag);
  auto ref = [&](const char* key) -> std::optional<SignalRef> {
    if (!p.has(key)) {
      p.text(key, "");
      return std::nullopt;
    }
    const auto name_ref = p.text(key);
    auto s = signal(name_ref);
    if (!s) p.fail(key, "no output '" + name_ref + "' (expected block.port)");
    return s;
  };
  monitor.show = ref("show");
  monitor.estimate = ref("estimate");
  monitor.truth = ref("truth");
  monitor.reference = ref("reference");
  for (const auto& r : p.texts("record", {})) {
    auto s = signal(r);
    if (!s) p.fail("record", "no output '" + r + "' (expected block.port)");
    else monitor.record.push_back(*s);
  }
  const auto hold = p.numbers("hold_s", {0.0, 0.0}, 2);
  monitor.hold_start_s = hold[0];
  monitor.hold_end_s = hold[1];
  p.check(hold[1] >= hold[0] && hold[0] >= 0, "hold_s", "expected [start, end] with 0 <= start <= end");
  monitor.settle_band = p.number("settle_band", 0.02);
  p.check(monitor.settle_band > 0 && monitor.settle_band < 1, "settle_band", "must be in (0, 1)");
  const std::size_t n = monitor.truth ? monitor.truth->size() : 0;
  if (monitor.truth && monitor.estimate && monitor.estimate->size() != n)
    p.fail("estimate", "must have as many elements as `truth` (" + std::to_string(n) + ")");
  if (monitor.truth && monitor.reference && monitor.reference->size() != n)
    p.fail("reference", "must have as many elements as `truth` (" + std::to_string(n) + ")");
  detail::report_unread_keys(p);
}

namespace {
bool valid_ipv4(const std::string& text) {
  in_addr a{};
  return inet_pton(AF_INET, text.c_str(), &a) == 1;
}

/// "10.0.0.2" or "10.0.0.2:7412".
bool valid_peer(const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) return valid_ipv4(text);
  const std::string port = text.substr(colon + 1);
  if (port.empty() || port.size() > 5 || !std::all_of(port.begin(), port.end(), ::isdigit)) return false;
  return valid_ipv4(text.substr(0, colon)) && std::stoi(port) <= 65535;
}

std::string resolve_relative(const std::string& path, const std::string& config_file) {
  if (path.empty() || path[0] == '/') return path;
  const auto slash = config_file.rfind('/');
  return slash == std::string::npos ? path : config_file.substr(0, slash + 1) + path;
}
}  // namespace

void Pipeline::Impl::parse_telemetry(const YAML::Node& t) {
  if (!t) return;
  if (!t.IsMap()) {
    error(detail::location_of(t, file), "telemetry", "expected a map");
    return;
  }
  Params p = detail::make_params(t, "telemetry", file, diag);
  TelemetrySpec& spec = telemetry;
  spec.enabled = true;
  const auto domain = p.integer("domain", 0);
  p.check(domain >= 0 && domain <= 232, "domain", "DDS domain id must be in 0..232, got " + std::to_string(domain));
  spec.domain = static_cast<int>(domain);
  const auto transport = p.choice("transport", {"loopback", "shm", "udp_loopback", "network"}, "loopback");
  spec.transport.kind = transport == "shm"            ? TransportSpec::Kind::shm
                        : transport == "udp_loopback" ? TransportSpec::Kind::udp_loopback
                        : transport == "network"      ? TransportSpec::Kind::network
                                                      : TransportSpec::Kind::loopback;
  if (auto net = p.optional_child("network")) {
    spec.transport.interfaces = net->texts("interfaces", {});
    for (std::size_t i = 0; i < spec.transport.interfaces.size(); ++i)
      net->check(valid_ipv4(spec.transport.interfaces[i]), "interfaces",
                 "interfaces[" + std::to_string(i) + "] '" + spec.transport.interfaces[i] +
                     "' is not an IPv4 address (give the address of the NIC, e.g. 192.168.10.5)");
    spec.transport.initial_peers = net->texts("initial_peers", {});
    for (std::size_t i = 0; i < spec.transport.initial_peers.size(); ++i)
      net->check(valid_peer(spec.transport.initial_peers[i]), "initial_peers",
                 "initial_peers[" + std::to_string(i) + "] '" + spec.transport.initial_peers[i] +
                     "' is not an IPv4 address or address:port");
    spec.transport.multicast = net->flag("multicast", true);
    if (spec.transport.kind != TransportSpec::Kind::network)
      net->fail("`network:` settings only apply with `transport: network` (now '" + transport + "')");
  }

  // Decimation: a published rate must divide the pipeline rate exactly, so every sample is
  // a cycle's value and not an interpolation.
  auto decimation_for = [&](Params& where, const std::string& key, double rate) -> std::uint32_t {
    if (!(rate > 0) || rate > rate_hz * (1 + 1e-12)) {
      where.fail(key, "rate " + std::to_string(rate) + " Hz must be in (0, " + std::to_string(rate_hz) +
                          "] (the pipeline rate)");
      return 1;
    }
    const double n = rate_hz / rate;
    const double rounded = std::round(n);
    if (std::abs(n - rounded) > 1e-9 * n) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "rate %g Hz does not divide the pipeline rate %g Hz; nearest rates: %g or %g Hz", rate,
                    rate_hz, rate_hz / std::ceil(n), rate_hz / std::max(1.0, std::floor(n)));
      where.fail(key, buf);
      return 1;
    }
    return static_cast<std::uint32_t>(rounded);
  };
  const double default_rate = p.number("rate_hz", std::min(rate_hz, 100.0));
  const std::uint32_t default_decimation = decimation_for(p, "rate_hz", default_rate);

  std::map<std::string, double> rates;
  if (auto r = p.optional_child("rates_hz"))
    for (const auto& key : r->keys()) rates[key] = r->number(key);
  for (const auto& ref : p.texts("publish", {})) {
    auto s = signal(ref);
    if (!s) {
      p.fail("publish", "no output '" + ref + "' (expected block.port; `lode describe` lists every output)");
      continue;
    }
    bool duplicate = false;
    for (const auto& existing : spec.signals) duplicate = duplicate || existing.signal.data == s->data;
    if (duplicate) {
      p.fail("publish", "'" + ref + "' is listed twice");
      continue;
    }
    TelemetrySignal ts;
    ts.signal = *s;
    ts.topic = signal_topic(name, s->block, s->port);
    ts.decimation = default_decimation;
    if (auto it = rates.find(ref); it != rates.end()) {
      ts.decimation = decimation_for(p, "rates_hz", it->second);
      rates.erase(it);
    }
    spec.signals.push_back(std::move(ts));
  }
  for (const auto& [ref, rate] : rates)
    p.fail("rates_hz", "'" + ref + "' has a rate but is not in `publish`");

  if (auto st = p.optional_child("state")) {
    auto ref = [&](const char* key, bool required) -> std::optional<SignalRef> {
      if (!required && !st->has(key)) return std::nullopt;
      const auto text = st->text(key);
      auto s = signal(text);
      if (!s && !text.empty()) st->fail(key, "no output '" + text + "' (expected block.port)");
      return s;
    };
    auto pose = ref("pose", true);
    auto twist = ref("twist", false);
    auto covariance = ref("covariance", false);
    const double state_rate = st->number("rate_hz", default_rate);
    const auto decimation = decimation_for(*st, "rate_hz", state_rate);
    if (pose) {
      StateSpec state;
      state.pose = *pose;
      state.twist = twist;
      state.covariance = covariance;
      state.decimation = decimation;
      state.topic = pipeline_topic(name, "state");
      if (covariance) {
        const std::size_t n_pose = pose->size();
        const std::size_t n_all = n_pose + (twist ? twist->size() : 0);
        const std::size_t c = covariance->size();
        st->check(c == n_pose * n_pose || c == n_all * n_all, "covariance",
                  "'" + covariance->name() + "' has " + std::to_string(c) + " elements; a covariance of the pose (" +
                      std::to_string(n_pose) + "x" + std::to_string(n_pose) + ")" +
                      (twist ? " or of pose and twist (" + std::to_string(n_all) + "x" + std::to_string(n_all) + ")" : "") +
                      " is expected");
      }
      spec.state = std::move(state);
    }
  }
  spec.reliable = p.choice("reliability", {"best_effort", "reliable"}, "best_effort") == "reliable";
  spec.publish_period_s = p.number("publish_period_ms", 1.0) * 1e-3;
  p.check(spec.publish_period_s >= 50e-6 && spec.publish_period_s <= 0.1, "publish_period_ms",
          "must be in [0.05, 100] ms (the publisher's polling period: latency vs CPU)");
  spec.timing_rate_hz = p.number("timing_rate_hz", 1.0);
  p.check(spec.timing_rate_hz > 0 && spec.timing_rate_hz <= 100, "timing_rate_hz", "must be in (0, 100] Hz");
  const auto ring = p.integer("ring_records", 0);
  p.check(ring >= 0 && ring <= (1 << 24), "ring_records", "must be in 0..16777216 (0 = one second of samples)");
  spec.ring_records = static_cast<std::uint32_t>(std::clamp<std::int64_t>(ring, 0, 1 << 24));
  const auto history = p.integer("history", 0);
  p.check(history >= 0 && history <= (1 << 20), "history", "must be in 0..1048576 (0 = one second of samples)");
  spec.history = static_cast<std::uint32_t>(std::clamp<std::int64_t>(history, 0, 1 << 20));

  if (auto c = p.optional_child("commands")) {
    spec.commands.enabled = c->flag("enabled", false);
    spec.commands.allow_hosts = c->texts("allow_hosts", {});
    for (std::size_t i = 0; i < spec.commands.allow_hosts.size(); ++i)
      c->check(valid_ipv4(spec.commands.allow_hosts[i]), "allow_hosts",
               "allow_hosts[" + std::to_string(i) + "] '" + spec.commands.allow_hosts[i] + "' is not an IPv4 address");
    spec.commands.allow_participants = c->texts("allow_participants", {});
  }
  if (auto sec = p.optional_child("security")) {
    auto path = [&](const char* key, bool required) {
      const std::string v = required ? sec->text(key) : sec->text(key, "");
      const std::string resolved = resolve_relative(v, file);
      if (!resolved.empty()) {
        std::ifstream f(resolved);
        sec->check(static_cast<bool>(f), key, "cannot read '" + resolved + "'");
      }
      return resolved;
    };
    spec.security.ca_certificate = path("ca_certificate", true);
    spec.security.certificate = path("certificate", true);
    spec.security.private_key = path("private_key", true);
    spec.security.permissions_ca = path("permissions_ca", false);
    if (spec.security.permissions_ca.empty()) spec.security.permissions_ca = spec.security.ca_certificate;
    spec.security.governance = path("governance", true);
    spec.security.permissions = path("permissions", true);
  }
  detail::report_unread_keys(p);
}

// --------------------------------------------------------------------------------------

Pipeline::Pipeline() : impl_(std::make_unique<Impl>()) {}

Pipeline::~Pipeline() {
  if (impl_ && impl_->active) deactivate();
  // Blocks own their models; both are destroyed here, while their libraries stay loaded.
}

std::unique_ptr<Pipeline> Pipeline::load_file(const std::string& path, PluginRegistry& registry,
                                              Diagnostics& diagnostics) {
  std::ifstream in(path);
  if (!in) {
    diagnostics.add({path, 0, 0}, "", "cannot open the pipeline file");
    return nullptr;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return load_text(ss.str(), path, registry, diagnostics);
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
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::ParserException& ex) {
    diagnostics.add({label, ex.mark.line + 1, ex.mark.column + 1}, "",
                    "YAML syntax error: " + ex.msg);
    return nullptr;
  }
  check_duplicate_keys(root, "", label, diagnostics);
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
  for (auto* b : order) im.configure_block(*b);
  im.resolve_inputs();
  if (!diagnostics.empty()) return nullptr;
  im.allocate_and_bind();
  im.build_ops(order);
  im.parse_monitor(root["monitor"]);
  im.parse_telemetry(root["telemetry"]);
  if (!diagnostics.empty()) return nullptr;
  return p;
}

const std::string& Pipeline::name() const { return impl_->name; }
const std::string& Pipeline::source_file() const { return impl_->file; }
double Pipeline::rate_hz() const { return impl_->rate_hz; }
std::int64_t Pipeline::period_ns() const {
  return static_cast<std::int64_t>(std::llround(1e9 / impl_->rate_hz));
}
const RealtimeSettings& Pipeline::realtime() const { return impl_->realtime; }
std::optional<double> Pipeline::default_duration_s() const { return impl_->duration_s; }
const MonitorSpec& Pipeline::monitor() const { return impl_->monitor; }
const TelemetrySpec& Pipeline::telemetry() const { return impl_->telemetry; }
const std::string& Pipeline::source_text() const { return impl_->source_text; }
std::vector<Pipeline::Op>& Pipeline::ops() { return impl_->ops; }
const std::vector<Pipeline::Op>& Pipeline::ops() const { return impl_->ops; }
std::optional<SignalRef> Pipeline::signal(const std::string& ref) const { return impl_->signal(ref); }

Block* Pipeline::block(const std::string& name) const {
  const BlockEntry* b = impl_->find_block(name);
  return b ? b->block.get() : nullptr;
}

std::vector<std::string> Pipeline::block_names() const {
  std::vector<std::string> out;
  for (const auto& b : impl_->blocks)
    if (b->block) out.push_back(b->name);
  return out;
}

std::vector<SignalRef> Pipeline::signals() const {
  std::vector<SignalRef> out;
  for (const auto& b : impl_->blocks)
    for (const auto& o : b->outputs) out.push_back({b->name, o.name, o.port->data(), &o.elements});
  return out;
}

Status Pipeline::activate() {
  std::fill(impl_->arena.begin(), impl_->arena.end(), 0.0);
  std::vector<Block*> activated;
  for (auto& b : impl_->blocks) {
    if (!b->block) continue;
    Status st;
    try {
      st = b->block->activate();
    } catch (const std::exception& ex) {
      st = Status::error(std::string("activate() threw: ") + ex.what());
    }
    if (!st) {
      // Nothing starts half-configured: undo what was activated.
      for (auto* a : activated) a->drive_safe();
      for (auto* a : activated) a->deactivate();
      return Status::error("block '" + b->name + "' failed to activate: " + st.message());
    }
    activated.push_back(b->block.get());
  }
  impl_->active = true;
  return {};
}

void Pipeline::deactivate() noexcept {
  if (!impl_->active) return;
  drive_safe();
  for (auto& b : impl_->blocks)
    if (b->block) b->block->deactivate();
  impl_->active = false;
}

void Pipeline::drive_safe() noexcept {
  for (auto& b : impl_->blocks)
    if (b->block && b->is_io()) b->block->drive_safe();
}

Pipeline::CycleResult Pipeline::run_cycle(const Tick& tick, bool time_ops) noexcept {
  auto& ops = impl_->ops;
  for (std::size_t i = 0; i < ops.size(); ++i) {
    Op& op = ops[i];
    const std::int64_t start = time_ops ? monotonic_ns() : 0;
    const StepStatus s = op.write_phase ? op.block->write(tick) : op.block->step(tick);
    if (time_ops) op.exec_time->record(monotonic_ns() - start);
    if (s != StepStatus::ok) {
      drive_safe();
      return {s, static_cast<int>(i)};
    }
  }
  return {};
}

Json Pipeline::describe() const {
  const Impl& im = *impl_;
  Json j = Json::object();
  j["pipeline"] = im.name;
  j["file"] = im.file;
  j["rate_hz"] = im.rate_hz;
  j["period_s"] = 1.0 / im.rate_hz;
  Json rt = Json::object();
  rt["priority"] = im.realtime.priority;
  rt["cpu"] = im.realtime.cpu;
  rt["lock_memory"] = im.realtime.lock_memory;
  rt["overrun_policy"] = im.realtime.overrun_policy == OverrunPolicy::stop       ? "stop"
                         : im.realtime.overrun_policy == OverrunPolicy::catch_up ? "catch_up"
                                                                                 : "skip";
  rt["max_overruns"] = im.realtime.max_overruns;
  j["realtime"] = std::move(rt);
  if (impl_->telemetry.enabled) {
    const auto& t = impl_->telemetry;
    Json tj = Json::object();
    tj["domain"] = static_cast<std::int64_t>(t.domain);
    tj["transport"] = to_string(t.transport.kind);
    Json topics = Json::array();
    for (const auto& s : t.signals) {
      Json sj = Json::object();
      sj["topic"] = s.topic;
      sj["signal"] = s.signal.name();
      sj["rate_hz"] = s.rate_hz(impl_->rate_hz);
      sj["decimation"] = static_cast<std::uint64_t>(s.decimation);
      topics.push(std::move(sj));
    }
    if (t.state) {
      Json sj = Json::object();
      sj["topic"] = t.state->topic;
      sj["signal"] = t.state->pose.name();
      sj["rate_hz"] = impl_->rate_hz / t.state->decimation;
      sj["decimation"] = static_cast<std::uint64_t>(t.state->decimation);
      topics.push(std::move(sj));
    }
    tj["topics"] = std::move(topics);
    tj["timing_topic"] = pipeline_topic(impl_->name, "timing");
    tj["events_topic"] = pipeline_topic(impl_->name, "events");
    tj["commands"] = t.commands.enabled;
    if (t.commands.enabled) tj["command_topic"] = pipeline_topic(impl_->name, "command");
    tj["security"] = t.security.enabled();
    j["telemetry"] = std::move(tj);
  }
  Json order = Json::array();
  for (const auto& op : im.ops) order.push(op.label);
  j["cycle_order"] = std::move(order);
  Json models = Json::object();
  for (const auto& [name, spec] : im.models) {
    Json m = to_json(spec.node);
    models[name] = std::move(m);
  }
  j["models"] = std::move(models);
  Json blocks = Json::object();
  for (const auto& b : im.blocks) {
    if (!b->block) continue;
    Json bj = Json::object();
    bj["plugin"] = b->plugin_name;
    bj["kind"] = to_string(b->plugin.descriptor->kind);
    bj["plugin_file"] = b->plugin.path;
    Json params = to_json(b->node);
    Json clean = Json::object();
    for (const auto& [k, v] : params.members())
      if (k != "plugin" && k != "inputs") clean[k] = v;
    bj["parameters"] = std::move(clean);
    Json ins = Json::object();
    for (const auto& d : b->inputs) {
      Json ij = Json::object();
      std::string src;
      for (const auto& w : b->wiring)
        if (w.input == d.name) src = w.source;
      ij["from"] = src.empty() ? Json() : Json(src);
      ij["required"] = d.required;
      if (!src.empty()) {
        auto s = im.signal(src);
        if (s) ij["elements"] = elements_json(*s->elements);
      } else {
        ij["elements"] = elements_json(d.expected);
      }
      ins[d.name] = std::move(ij);
    }
    bj["inputs"] = std::move(ins);
    Json outs = Json::object();
    for (const auto& o : b->outputs) outs[o.name] = elements_json(o.elements);
    bj["outputs"] = std::move(outs);
    Json derived = Json::object();
    b->block->describe(derived);
    bj["derived"] = std::move(derived);
    blocks[b->name] = std::move(bj);
  }
  j["blocks"] = std::move(blocks);
  return j;
}

}  // namespace lode
