#include "lode/clock.hpp"
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
#include "lode/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

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


namespace {

constexpr const char* kTopLevelKeys[] = {"pipeline", "rate_hz",   "duration_s", "realtime", "models", "blocks",
                                         "monitor",  "telemetry", "health",     "record",   "envelope"};
/// Keys of a block that the pipeline reads (the rest are the plugin's parameters).
const std::vector<std::string> kPipelineBlockKeys = {"plugin", "inputs", "shadow_of", "shadow_decimation"};
/// Outputs the pipeline adds to every shadow role.
constexpr const char* kDisagreementPort = "disagreement";
constexpr const char* kNisPort = "nis";


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

}  // namespace


// --------------------------------------------------------------------------------------
// The context each block's configure() sees.
class LoaderContext final : public ConfigureContext {
 public:
  LoaderContext(Pipeline::Impl& p, BlockEntry& e, Params& params)
      : p_(p), e_(e), params_(params) {}

  Params& params() override { return params_; }
  [[nodiscard]] const std::string& block_name() const override { return e_.name; }
  /// A decimated shadow runs at a fraction of the pipeline rate: its discretisation must know.
  [[nodiscard]] double rate_hz() const override { return p_.rate_hz / e_.shadow_decimation; }

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
  std::set<std::string> documented(kPipelineBlockKeys.begin(), kPipelineBlockKeys.end());
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
            "rate_hz must be a number in (0, 100000], got '" + (rate.IsScalar() ? rate.Scalar() : "?") + "'");
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

std::vector<BlockEntry*> Pipeline::Impl::order_blocks() {
  // io blocks are sources (read phase) and sinks (write phase): edges into them never
  // constrain the order, so feedback through the plant is not a cycle.
  std::vector<BlockEntry*> io, rest;
  std::vector<BlockEntry*> feeds;
  std::vector<BlockEntry*> shadows;  // configured after everything else, not in the cycle order
  for (auto& b : blocks) {
    if (!b->shadow_of.empty()) { shadows.push_back(b.get()); continue; }
    (!b->plugin.descriptor && b->configured ? feeds : b->is_io() ? io : rest).push_back(b.get());
  }
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
  if (order.size() + feeds.size() + shadows.size() != blocks.size()) {
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
  order.insert(order.end(), shadows.begin(), shadows.end());
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
  Params params = detail::make_params(e.node, path, file, diag, kPipelineBlockKeys);
  LoaderContext ctx(*this, e, params);
  Status st;
  bool threw = true;
  try {
    st = e.block->configure(ctx);
    threw = false;
  } catch (const std::exception& ex) {
    st = Status::error(std::string("configure() threw: ") + ex.what());
  } catch (...) {
    st = Status::error("configure() threw a non-standard exception");
  }
  if (threw) {  // keys it never got to read are not the user's mistake: report the bug only
    error(e.where, path, st.message());
    e.configured = true;
    return;
  }
  detail::report_unread_keys(params);
  check_documented(e.plugin, params, path);
  if (!st && params.ok()) error(e.where, path, st.message());
  e.configured = true;
}

void Pipeline::Impl::resolve_inputs() {
  for (auto& b : blocks)
    if (b->block) resolve_inputs_of(*b);
}

void Pipeline::Impl::resolve_inputs_of(BlockEntry& entry) {
  {
    BlockEntry* b = &entry;
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
  for (auto& b : blocks) {
    for (auto& o : b->outputs) PortBinder::bind(*o.port, arena.data() + o.offset, o.elements.size());
    b->live.store(b.get(), std::memory_order_relaxed);
  }
  for (auto& b : blocks) bind_inputs(*b);
}

void Pipeline::Impl::bind_inputs(BlockEntry& record) {
  for (auto& d : record.inputs)
    for (const auto& w : record.wiring) {
      if (w.input != d.name) continue;
      const BlockEntry* src = find_block(w.src_block);
      const DeclaredOutput* out = src ? src->output(w.src_port) : nullptr;
      if (out) PortBinder::bind(*d.port, arena.data() + out->offset, out->elements.size());
    }
}

void Pipeline::Impl::check_shadows(const std::vector<BlockEntry*>& order) {
  for (auto* b : order) {
    if (b->shadow_of.empty() || !b->block) continue;
    const std::string path = "blocks." + b->name + ".shadow_of";
    BlockEntry* primary = find_block(b->shadow_of);
    if (!primary || !primary->block) continue;  // reported already
    // A shadow must be able to take its primary's place (promotion, fallback): every output
    // of the primary, with the same elements.
    for (const auto& po : primary->outputs) {
      const DeclaredOutput* so = b->output(po.name);
      std::string problem;
      if (!so) {
        problem = "it has no output '" + po.name + "'";
      } else if (so->elements.size() != po.elements.size()) {
        problem = "its output '" + po.name + "' has " + std::to_string(so->elements.size()) + " elements, " +
                  b->shadow_of + "." + po.name + " has " + std::to_string(po.elements.size());
      } else {
        for (std::size_t i = 0; i < po.elements.size() && problem.empty(); ++i)
          if (so->elements[i].unit != po.elements[i].unit)
            problem = "its output '" + po.name + "." + so->elements[i].name + "' is in '" + so->elements[i].unit +
                      "', " + b->shadow_of + "." + po.name + "." + po.elements[i].name + " in '" +
                      po.elements[i].unit + "'";
      }
      if (!problem.empty())
        error(b->shadow_where, path,
              "shadow '" + b->name + "' (" + b->plugin_name + ") cannot stand in for '" + b->shadow_of + "' (" +
                  primary->plugin_name + "): " + problem +
                  " (a shadow must provide every output of its primary, same size and units)");
    }
    for (const auto& o : b->outputs)
      if (o.name == kDisagreementPort || o.name == kNisPort)
        error(b->shadow_where, path, "plugin " + b->plugin_name + " declares an output '" + o.name +
                                         "', a name the pipeline reserves on shadows for their statistics");
    // Its inputs must be computed before the primary steps (it runs right after it).
    std::set<const BlockEntry*> before;
    for (auto* o : order) {
      if (o == primary) break;
      before.insert(o);
    }
    for (const auto& w : b->wiring) {
      const BlockEntry* src = find_block(w.src_block);
      if (src && !src->is_io() && !before.count(src) && src->configured && src->block)
        error(w.where, "blocks." + b->name + ".inputs." + w.input,
              "'" + w.source + "' is computed after '" + b->shadow_of +
                  "' in the cycle; a shadow steps right after its primary and can only read what the "
                  "primary could");
    }
    if (primary->outputs.empty()) {
      error(b->shadow_where, path, "'" + b->shadow_of + "' has no outputs: there is nothing to shadow");
      continue;
    }
    // Statistics the pipeline publishes for the shadow: disagreement with the primary (on the
    // primary's first output) and the normalised innovation squared.
    const DeclaredOutput& first = primary->outputs.front();
    Elements diff = first.elements;
    b->outputs.push_back({kDisagreementPort, diff, &synthetic_ports.emplace_back(), 0, true});
    b->outputs.push_back({kNisPort, Elements{{"nis", "1"}}, &synthetic_ports.emplace_back(), 0, true});
  }
}

std::vector<Binding> Pipeline::Impl::plan_for(BlockEntry& record, const BlockEntry& role) {
  std::vector<Binding> plan;
  for (auto& o : record.outputs) {
    if (o.synthetic) continue;
    const DeclaredOutput* target = role.output(o.name);
    bool same = target && !target->synthetic && target->elements.size() == o.elements.size();
    for (std::size_t i = 0; same && i < o.elements.size(); ++i)
      same = units_compatible(o.elements[i].unit, target->elements[i].unit) &&
             units_compatible(target->elements[i].unit, o.elements[i].unit);
    double* data = same ? arena.data() + target->offset : record.staging.data() + o.offset;
    plan.push_back({o.port, data, o.elements.size()});
  }
  return plan;
}

void Pipeline::Impl::prepare_record(BlockEntry& record, const Family& family) {
  // Staging: the record's own storage (offsets of a role's outputs are arena offsets; the
  // staging copy is laid out the same way, one slot per element).
  std::size_t size = 0;
  if (record.candidate) {
    size = 0;
    for (auto& o : record.outputs) {
      o.offset = size;
      size += o.elements.size();
    }
  } else {
    // Roles keep their arena offsets; give staging the same span.
    size = 0;
    for (auto& o : record.outputs)
      if (!o.synthetic) size = std::max(size, o.offset + o.elements.size());
  }
  record.staging.assign(size, 0.0);
  record.staging_plan.clear();
  for (auto& o : record.outputs)
    if (!o.synthetic) record.staging_plan.push_back({o.port, record.staging.data() + o.offset, o.elements.size()});
  record.plans.clear();
  for (const BlockEntry* role : family.roles) record.plans.push_back(plan_for(record, *role));
  record.layout = record.block ? record.block->state_layout() : StateLayout{};
}

void Pipeline::Impl::build_ops(const std::vector<BlockEntry*>& order) {
  for (auto* b : order) {
    if (!b->block || !b->shadow_of.empty()) continue;
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

void Pipeline::Impl::build_families() {
  for (std::size_t i = 0; i < ops.size(); ++i) {
    if (ops[i].write_phase) continue;
    BlockEntry* primary = nullptr;
    for (auto& b : blocks)
      if (b->block.get() == ops[i].block) primary = b.get();
    if (!primary || primary->is_io()) continue;  // io blocks own hardware: not swappable
    Family f;
    f.primary = primary;
    f.op = i;
    f.roles.push_back(primary);
    for (auto& b : blocks)
      if (b->shadow_of == primary->name && b->block && !primary->outputs.empty()) f.roles.push_back(b.get());
    for (std::size_t r = 1; r < f.roles.size(); ++r) {
      BlockEntry* role = f.roles[r];
      ShadowSlot slot;
      slot.block = role->block.get();
      slot.role = role;
      slot.decimation = role->shadow_decimation;
      const DeclaredOutput& first = primary->outputs.front();
      slot.primary = arena.data() + first.offset;
      slot.mine = arena.data() + output_offset(*role, first.name);
      slot.disagreement = arena.data() + output_offset(*role, kDisagreementPort);
      slot.disagreement_size = first.elements.size();
      slot.nis = arena.data() + output_offset(*role, kNisPort);
      slot.nu.assign(std::max<std::size_t>(1, role->block->innovation_size()), 0.0);
      slot.s.assign(slot.nu.size(), 0.0);
      f.shadows.push_back(std::move(slot));
    }
    for (const auto& o : primary->outputs) f.ranges.push_back({arena.data() + o.offset, nullptr, o.elements.size()});
    ops[i].family = static_cast<int>(families.size());
    for (std::size_t r = 0; r < f.roles.size(); ++r) {
      f.roles[r]->family = static_cast<int>(families.size());
      f.roles[r]->family_role = static_cast<int>(r);
    }
    families.push_back(std::move(f));
  }
  for (auto& f : families)
    for (auto* role : f.roles) prepare_record(*role, f);
}

std::vector<BlockEntry*> Pipeline::Impl::instances() {
  std::vector<BlockEntry*> out;
  for (auto& b : blocks)
    if (b->block) out.push_back(b.get());
  for (auto& c : pool)
    if (c->block) out.push_back(c.get());
  return out;
}

void Pipeline::Impl::exchange_roles(Family& f, int role_a, int role_b) noexcept {
  BlockEntry* a = f.roles[static_cast<std::size_t>(role_a)]->live.load(std::memory_order_relaxed);
  BlockEntry* b = f.roles[static_cast<std::size_t>(role_b)]->live.load(std::memory_order_relaxed);
  for (const auto& bind : a->plans[static_cast<std::size_t>(role_b)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  for (const auto& bind : b->plans[static_cast<std::size_t>(role_a)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  auto set_instance = [&](int role, BlockEntry* record) {
    if (role == 0) ops[f.op].block = record->block.get();
    else f.shadows[static_cast<std::size_t>(role - 1)].block = record->block.get();
    f.roles[static_cast<std::size_t>(role)]->live.store(record, std::memory_order_release);
  };
  set_instance(role_a, b);
  set_instance(role_b, a);
}

BlockEntry* Pipeline::Impl::install(Family& f, int role, BlockEntry& record) noexcept {
  BlockEntry* old = f.roles[static_cast<std::size_t>(role)]->live.load(std::memory_order_relaxed);
  for (const auto& bind : old->staging_plan) PortBinder::bind(*bind.port, bind.data, bind.size);
  for (const auto& bind : record.plans[static_cast<std::size_t>(role)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  if (role == 0) ops[f.op].block = record.block.get();
  else f.shadows[static_cast<std::size_t>(role - 1)].block = record.block.get();
  f.roles[static_cast<std::size_t>(role)]->live.store(&record, std::memory_order_release);
  return old;
}

void Pipeline::Impl::push_trip(const TripRecord& t) noexcept {
  const std::uint64_t head = trip_head.load(std::memory_order_relaxed);
  if (head - trip_tail.load(std::memory_order_acquire) >= kTripCapacity) {
    trips_lost.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  trips[head % kTripCapacity] = t;
  trip_head.store(head + 1, std::memory_order_release);
}

namespace {
/// In-place Cholesky test of a symmetric n x n row-major matrix (destroys `a`). True when
/// positive definite. No allocation: the health monitor runs it on the RT thread.
bool positive_definite(double* a, std::size_t n) noexcept {
  for (std::size_t j = 0; j < n; ++j) {
    double d = a[j * n + j];
    for (std::size_t k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double l = std::sqrt(d);
    a[j * n + j] = l;
    for (std::size_t i = j + 1; i < n; ++i) {
      double v = a[i * n + j];
      for (std::size_t k = 0; k < j; ++k) v -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = v / l;
    }
  }
  return true;
}
}  // namespace

StepStatus Pipeline::Impl::after_primary(Family& f, const Tick& tick, StepStatus status, std::int64_t step_ns,
                                         const char*& reason) noexcept {
  // Shadows run on the inputs the primary just used; their faults are counted, never fatal.
  for (auto& slot : f.shadows) {
    slot.stepped_ok = false;
    if (slot.decimation > 1 && tick.cycle % slot.decimation != 0) continue;
    Tick t = tick;
    t.dt_s = tick.dt_s * slot.decimation;
    if (slot.block->step(t) != StepStatus::ok) {
      ++slot.faults;
      continue;
    }
    slot.stepped_ok = true;
    for (std::size_t i = 0; i < slot.disagreement_size; ++i) slot.disagreement[i] = slot.mine[i] - slot.primary[i];
    double nis = std::numeric_limits<double>::quiet_NaN();
    const std::size_t m = slot.block->innovation_size();
    if (m > 0 && m <= slot.nu.size() && slot.block->innovation(slot.nu.data(), slot.s.data())) {
      nis = 0.0;
      for (std::size_t i = 0; i < m; ++i) nis += slot.nu[i] * slot.nu[i] / slot.s[i];
    }
    *slot.nis = nis;
  }
  if (f.warming) {
    f.warming->step(tick);  // a failing candidate is caught when it is installed (health)
    if (f.warming_left > 0) --f.warming_left;
  }
  const HealthSpec& h = f.health;
  if (!h.enabled) return status;

  const char* trip = nullptr;
  Block* primary = ops[f.op].block;
  if (status != StepStatus::ok) trip = primary->fault_reason();
  if (!trip && h.non_finite)
    for (const auto& r : f.ranges)
      for (std::size_t i = 0; i < r.size && !trip; ++i)
        if (!std::isfinite(r.primary[i])) trip = "non-finite output";
  BlockEntry* live = f.roles[0]->live.load(std::memory_order_relaxed);
  if (!trip && h.covariance_every > 0 && live->layout.covariance && tick.cycle % h.covariance_every == 0 &&
      f.state_values.size() >= live->layout.size() &&
      f.state_covariance.size() >= live->layout.size() * live->layout.size()) {
    primary->export_state(f.state_values.data(), f.state_covariance.data());
    for (std::size_t i = 0; i < live->layout.size() && !trip; ++i)
      if (!std::isfinite(f.state_values[i])) trip = "non-finite state";
    if (!trip && !positive_definite(f.state_covariance.data(), live->layout.size()))
      trip = "covariance not positive definite";
  }
  if (!trip && h.nis_window > 0) {
    const std::size_t m = primary->innovation_size();
    if (m > 0 && m <= f.nu.size() && primary->innovation(f.nu.data(), f.s.data())) {
      double nis = 0.0;
      for (std::size_t i = 0; i < m; ++i) nis += f.nu[i] * f.nu[i] / f.s[i];
      if (f.nis_count == h.nis_window) f.nis_sum -= f.nis_ring[f.nis_pos];
      else ++f.nis_count;
      f.nis_ring[f.nis_pos] = nis;
      f.nis_sum += nis;
      f.nis_pos = (f.nis_pos + 1) % h.nis_window;
      if (!std::isfinite(nis)) trip = "non-finite innovation";
      else if (f.nis_count == h.nis_window && f.nis_sum / h.nis_window > h.nis_threshold)
        trip = "innovation test failed (windowed mean NIS over threshold)";
    }
  }
  if (!trip && h.step_budget_ns > 0) {
    f.over_budget = step_ns > h.step_budget_ns ? f.over_budget + 1 : 0;
    if (f.over_budget >= h.budget_cycles) trip = "step time over budget";
  }
  if (!trip) return status;

  TripRecord record;
  record.cycle = tick.cycle;
  record.time_ns = tick.time_ns;
  record.family = static_cast<int>(&f - families.data());
  record.reason = trip;
  const int slot_index = h.fallback_slot;
  if (slot_index >= 0 && !f.fallback_used && f.shadows[static_cast<std::size_t>(slot_index)].stepped_ok) {
    // The fallback already stepped on this cycle's inputs: exchange roles and hand its outputs
    // to the primary storage now, so the blocks downstream use them in this very cycle.
    auto& slot = f.shadows[static_cast<std::size_t>(slot_index)];
    bool finite = true;
    for (const auto& r : f.ranges)
      for (std::size_t i = 0; i < r.size; ++i) finite = finite && std::isfinite(r.shadow[i]);
    if (finite) {
      exchange_roles(f, 0, slot_index + 1);
      for (const auto& r : f.ranges) std::memcpy(r.primary, r.shadow, r.size * sizeof(double));
      (void)slot;
      f.fallback_used = true;
      f.nis_count = 0;
      f.nis_sum = 0.0;
      f.nis_pos = 0;
      f.over_budget = 0;
      record.fallback_slot = slot_index;
      push_trip(record);
      return StepStatus::ok;
    }
  }
  push_trip(record);
  reason = trip;
  return StepStatus::fault;
}

std::optional<SignalRef> Pipeline::Impl::signal(const std::string& ref) const {
  const auto dot = ref.find('.');
  if (dot == std::string::npos) return std::nullopt;
  const BlockEntry* b = find_block(ref.substr(0, dot));
  if (!b) return std::nullopt;
  const DeclaredOutput* o = b->output(ref.substr(dot + 1));
  // The role's storage in the arena (never the port: a hot swap re-binds ports).
  if (!o || arena.empty() || o->offset + o->elements.size() > arena.size()) return std::nullopt;
  return SignalRef{b->name, o->name, arena.data() + o->offset, &o->elements};
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
  im.parse_envelope(root["envelope"]);
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
const RecordSettings& Pipeline::record_settings() const { return impl_->record_settings; }
const MonitorSpec& Pipeline::monitor() const { return impl_->monitor; }
const TelemetrySpec& Pipeline::telemetry() const { return impl_->telemetry; }
const std::string& Pipeline::source_text() const { return impl_->source_text; }
std::vector<Pipeline::Op>& Pipeline::ops() { return impl_->ops; }
const std::vector<Pipeline::Op>& Pipeline::ops() const { return impl_->ops; }
std::optional<SignalRef> Pipeline::signal(const std::string& ref) const { return impl_->signal(ref); }

Block* Pipeline::block(const std::string& name) const {
  const BlockEntry* b = impl_->find_block(name);
  if (!b) return nullptr;
  const BlockEntry* live = b->live.load(std::memory_order_acquire);
  return live ? live->block.get() : b->block.get();
}

Block* const* Pipeline::block_slot(const std::string& name) const {
  const BlockEntry* b = impl_->find_block(name);
  if (!b || !b->block) return nullptr;
  if (b->family >= 0) {
    Family& f = impl_->families[static_cast<std::size_t>(b->family)];
    return b->family_role == 0 ? &impl_->ops[f.op].block
                               : &f.shadows[static_cast<std::size_t>(b->family_role - 1)].block;
  }
  for (const auto& op : impl_->ops)
    if (op.block == b->block.get()) return &op.block;
  return nullptr;
}

std::string Pipeline::plugin_of(const std::string& name) const {
  const BlockEntry* b = impl_->find_block(name);
  if (!b) return {};
  const BlockEntry* live = b->live.load(std::memory_order_acquire);
  return live ? live->plugin_name : b->plugin_name;
}

std::vector<std::string> Pipeline::block_names() const {
  std::vector<std::string> out;
  for (const auto& b : impl_->blocks)
    if (b->block) out.push_back(b->name);
  return out;
}

std::vector<Pipeline::ShadowInfo> Pipeline::shadows() const {
  std::vector<ShadowInfo> out;
  for (const auto& b : impl_->blocks)
    if (!b->shadow_of.empty()) out.push_back({b->name, b->shadow_of});
  return out;
}

std::vector<SignalRef> Pipeline::signals() const {
  // Role storage (arena), never through a port: a hot swap re-binds ports, not storage.
  std::vector<SignalRef> out;
  for (const auto& b : impl_->blocks)
    for (const auto& o : b->outputs) out.push_back({b->name, o.name, impl_->arena.data() + o.offset, &o.elements});
  return out;
}

std::vector<Pipeline::HealthTrip> Pipeline::take_health_trips() {
  std::vector<HealthTrip> out;
  auto& im = *impl_;
  const std::uint64_t head = im.trip_head.load(std::memory_order_acquire);
  std::uint64_t tail = im.trip_tail.load(std::memory_order_relaxed);
  for (; tail < head; ++tail) {
    const TripRecord& t = im.trips[tail % Impl::kTripCapacity];
    HealthTrip h;
    h.cycle = t.cycle;
    h.time_ns = t.time_ns;
    h.reason = t.reason;
    if (t.family >= 0) {
      const Family& f = im.families[static_cast<std::size_t>(t.family)];
      h.block = f.primary->name;
      if (t.fallback_slot >= 0) {
        const BlockEntry* role = f.roles[static_cast<std::size_t>(t.fallback_slot + 1)];
        h.fallback = role->name;
        // After the exchange the fallback's instance runs in the primary role.
        const BlockEntry* live = f.roles[0]->live.load(std::memory_order_acquire);
        h.fallback_plugin = live ? live->plugin_name : "";
      }
    }
    out.push_back(std::move(h));
  }
  im.trip_tail.store(tail, std::memory_order_release);
  const auto lost = im.trips_lost.exchange(0, std::memory_order_relaxed);
  if (lost > 0) {
    HealthTrip h;
    h.reason = "health trips lost (ring full)";
    h.lost = lost;
    out.push_back(std::move(h));
  }
  return out;
}

Status Pipeline::activate() {
  std::fill(impl_->arena.begin(), impl_->arena.end(), 0.0);
  impl_->envelope.reset();
  std::vector<Block*> activated;
  for (auto* b : impl_->instances()) {
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
  for (auto& f : impl_->families) {
    f.fallback_used = false;
    f.nis_count = 0;
    f.nis_sum = 0.0;
    f.nis_pos = 0;
    f.over_budget = 0;
  }
  impl_->active = true;
  return {};
}

void Pipeline::deactivate() noexcept {
  if (!impl_->active) return;
  drive_safe();
  for (auto& b : impl_->blocks)
    if (b->block) b->block->deactivate();
  for (auto& c : impl_->pool)
    if (c->block) c->block->deactivate();
  impl_->active = false;
}

void Pipeline::drive_safe() noexcept {
  for (auto& b : impl_->blocks)
    if (b->block && b->is_io()) b->block->drive_safe();
}

std::string Pipeline::envelope_violation() const { return impl_->envelope.violation_text(); }

Pipeline::CycleResult Pipeline::run_cycle(const Tick& tick, bool time_ops) noexcept {
  auto& ops = impl_->ops;
  const bool supervised = !impl_->envelope.empty();
  for (std::size_t i = 0; i < ops.size(); ++i) {
    if (supervised && i == impl_->envelope_at && !impl_->envelope.check(tick)) {
      drive_safe();
      return {StepStatus::fault, static_cast<int>(i), nullptr, true};
    }
    Op& op = ops[i];
    Family* family = op.family >= 0 ? &impl_->families[static_cast<std::size_t>(op.family)] : nullptr;
    const bool timed = time_ops || (family && family->health.step_budget_ns > 0);
    const std::int64_t start = timed ? monotonic_ns() : 0;
    StepStatus s = op.write_phase ? op.block->write(tick) : op.block->step(tick);
    const std::int64_t elapsed = timed ? monotonic_ns() - start : 0;
    if (time_ops) op.exec_time->record(elapsed);
    const char* reason = nullptr;
    if (family && (family->health.enabled || !family->shadows.empty() || family->warming))
      s = impl_->after_primary(*family, tick, s, elapsed, reason);
    if (s != StepStatus::ok) {
      drive_safe();
      return {s, static_cast<int>(i), reason};
    }
  }
  if (supervised && impl_->envelope_at == ops.size() && !impl_->envelope.check(tick)) {
    drive_safe();
    return {StepStatus::fault, static_cast<int>(ops.size()) - 1, nullptr, true};
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
  rt["spin_us"] = im.realtime.spin_us;
  rt["clock"] = im.realtime.real_clock ? "real" : "sim";
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
  for (const auto& role : im.blocks) {
    if (!role->block && role->live.load() == role.get()) continue;
    // The instance now in the role (a hot swap or promotion may have changed it).
    const BlockEntry* b = role->live.load(std::memory_order_acquire);
    if (!b || !b->block) b = role.get();
    if (!b->block) continue;
    Json bj = Json::object();
    bj["plugin"] = b->plugin_name;
    bj["kind"] = to_string(b->plugin.descriptor->kind);
    bj["plugin_file"] = b->plugin.path;
    if (!role->shadow_of.empty()) {
      bj["shadow_of"] = role->shadow_of;
      bj["shadow_decimation"] = static_cast<std::uint64_t>(role->shadow_decimation);
    }
    if (b != role.get()) bj["swapped_in_from"] = b->name;
    Json params = to_json(b->node);
    Json clean = Json::object();
    for (const auto& [k, v] : params.members())
      if (std::find(kPipelineBlockKeys.begin(), kPipelineBlockKeys.end(), k) == kPipelineBlockKeys.end()) clean[k] = v;
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
    for (const auto& o : role->outputs) outs[o.name] = elements_json(o.elements);
    bj["outputs"] = std::move(outs);
    if (!b->layout.empty()) {
      Json st = Json::object();
      st["elements"] = elements_json(b->layout.elements);
      st["covariance"] = b->layout.covariance;
      bj["state"] = std::move(st);
    }
    Json derived = Json::object();
    b->block->describe(derived);
    bj["derived"] = std::move(derived);
    blocks[role->name] = std::move(bj);
  }
  j["blocks"] = std::move(blocks);
  return j;
}

}  // namespace lode
