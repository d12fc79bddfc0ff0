// Configuring each block: the context its configure() sees (parameters, models, ports), the
// checks on what it declares, and resolving its inputs to the outputs they name.
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

/// The entry of the plugin's port table that port `name` is, or nullptr. "<...>" entries stand
/// for names taken from the configuration.
const PortSpec* port_table_entry(const PluginDescriptor& d, const std::string& name) {
  const PortSpec* pattern = nullptr;
  for (std::size_t i = 0; i < d.port_count; ++i) {
    if (name == d.ports[i].name) return &d.ports[i];
    if (d.ports[i].name[0] == '<') pattern = &d.ports[i];
  }
  return pattern;
}

/// "input" or "output", for messages.
std::string port_word(PortDirection direction) { return direction == PortDirection::in ? "input" : "output"; }

}  // namespace

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
    if (!listed(name, PortDirection::out)) return;
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
    if (!listed(name, PortDirection::in)) return;
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
    return noted(p_.make_model<PlantModel>(params_, key, "plant"));
  }
  std::unique_ptr<MeasurementModel> measurement_model(std::string_view key) override {
    return noted(p_.make_model<MeasurementModel>(params_, key, "sensor"));
  }
  std::unique_ptr<ProcessModel> process_model(std::string_view key) override {
    return noted(p_.make_model<ProcessModel>(params_, key, "process"));
  }
  std::vector<std::unique_ptr<MeasurementModel>> measurement_models(std::string_view key) override {
    std::vector<std::unique_ptr<MeasurementModel>> out;
    for (const auto& name : params_.texts(key, {})) {
      auto m = noted(p_.make_model_named<MeasurementModel>(params_, key, name, "sensor"));
      if (m) out.push_back(std::move(m));
    }
    if (!params_.has(key)) params_.fail(key, "missing required parameter (a list of model names)");
    return out;
  }

  /// Whether the block asked for a model that failed on its own (its plugin did not load, or
  /// its configuration was refused): reported there, so the block's "model not available"
  /// is a consequence.
  [[nodiscard]] bool asked_for_failed_model() const { return asked_for_failed_model_; }

 private:
  /// No model, and nothing said against this block's parameters: the model itself failed.
  template <typename M>
  std::unique_ptr<M> noted(std::unique_ptr<M> model) {
    if (!model && params_.ok()) asked_for_failed_model_ = true;
    return model;
  }
  bool asked_for_failed_model_ = false;

  /// The port table is the one declaration of a plugin's ports: a port it does not list, or
  /// lists the other way round, is a bug in the plugin, reported as one.
  bool listed(const std::string& name, PortDirection direction) {
    const PortSpec* spec = port_table_entry(*e_.plugin.descriptor, name);
    if (!spec) {
      params_.fail("plugin " + e_.plugin_name + " declared " + port_word(direction) +
                   " '" + name + "' that its port table does not list (a bug in the plugin)");
      return false;
    }
    if (spec->direction != direction) {
      params_.fail("plugin " + e_.plugin_name + " declared '" + name + "' as an " +
                   port_word(direction) + " but its port table lists it as an " + port_word(spec->direction) +
                   " (a bug in the plugin)");
      return false;
    }
    return true;
  }

  Pipeline::Impl& p_;
  BlockEntry& e_;
  Params& params_;
};

/// After a successful configure(): every port the table lists without a condition was declared.
void check_unconditional_ports(const BlockEntry& e, Params& params) {
  const PluginDescriptor& d = *e.plugin.descriptor;
  for (std::size_t i = 0; i < d.port_count; ++i) {
    const PortSpec& spec = d.ports[i];
    if (spec.condition || spec.name[0] == '<') continue;
    const bool declared =
        spec.direction == PortDirection::out
            ? e.output(spec.name) != nullptr
            : std::any_of(e.inputs.begin(), e.inputs.end(), [&](const DeclaredInput& in) { return in.name == spec.name; });
    if (!declared)
      params.fail(std::string("plugin ") + d.name + " did not declare " + port_word(spec.direction) + " '" +
                  spec.name + "', which its port table lists as always present (a bug in the plugin)");
  }
}

template <typename M>
std::unique_ptr<M> Pipeline::Impl::make_model_named(Params& block_params, std::string_view key,
                                                    const std::string& model_name,
                                                    const char* needed) {
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
                               needed + " model");
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


void Pipeline::Impl::configure_block(BlockEntry& e) {
  if (!e.plugin.descriptor) return;
  // A block reading from one whose plugin is missing or whose configuration failed would refuse
  // its own for want of that input's elements ("must be connected to a configured block's
  // output"): the first problem is reported, not its echoes.
  for (const auto& w : e.wiring) {
    const BlockEntry* src = find_block(w.src_block);
    if (src && (src->failed || (!src->configured && src->plugin.descriptor == nullptr))) {
      e.failed = true;
      e.configured = true;
      return;
    }
  }
  const std::string path = "blocks." + e.name;
  std::unique_ptr<Component> made(e.plugin.descriptor->create());
  auto* block = dynamic_cast<Block*>(made.get());
  if (!block) {
    error(e.where, path, std::string("plugin ") + e.plugin.descriptor->name + " did not create a Block");
    e.failed = true;
    return;
  }
  made.release();
  e.adopt(std::unique_ptr<Block>(block));
  // Boards, and only boards, have a write phase and a safe state.
  if (e.is_io() != (e.board != nullptr)) {
    error(e.where, path, std::string("plugin ") + e.plugin.descriptor->name + " is of kind " +
                             to_string(e.plugin.descriptor->kind) +
                             (e.board ? " but implements lode::Board (only io plugins do)"
                                      : " but does not implement lode::Board (write phase and safe state)"));
    e.adopt(nullptr);
    e.failed = true;
    return;
  }
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
    e.failed = true;
    return;
  }
  e.failed = !st;
  if (st) check_unconditional_ports(e, params);
  detail::report_unread_keys(params);
  check_documented(e.plugin, params, path);
  // A block refused for want of a model that failed is said at the model, once.
  if (!st && params.ok() && !ctx.asked_for_failed_model()) error(e.where, path, st.message());
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
      // Reported already (a feed has no block but is configured; a failed block's outputs are
      // what it did not get to declare).
      if (!src || !src->configured || src->failed) continue;
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

}  // namespace lode
