// Hot swap, off the RT thread: building the newcomer (plugin, parameters, wiring, the
// loader's configuration and stand-in checks, storage, the state hand-over map) before the
// RT thread exchanges it at a cycle boundary.
#include "lode/sdk/clock.hpp"
#include "lode/hot_swap.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <thread>

#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "roles.hpp"

#include "hot_swap_prepared.hpp"

namespace lode {

using namespace pipeline_detail;
using namespace hot_swap_detail;

// ------------------------------------------------------------------------------------------
// Off the RT thread: build the newcomer.

Expected<HotSwap::PreparedPtr> HotSwap::prepare(const SwapRequest& request) {
  const std::int64_t start = monotonic_ns();
  auto fail = [&](const std::string& why) {
    return Expected<PreparedPtr>(Status::error("swap " + request.block + ": " + why));
  };
  BlockEntry* role = roles_.find(request.block);
  if (!role || (!role->block && role->live.load() == role))
    return fail("no swappable block '" + request.block + "' (swappable: " + join(roles_.swappable()) + ")");
  if (role->family < 0)
    return fail("'" + request.block + "' is " + (role->is_io() ? "an io block: it owns hardware and is not hot-swappable" : "not swappable"));
  Family& family = roles_.family_of(*role);
  if (request.shadow_cycles > 0 && !running_.load(std::memory_order_acquire))
    return fail("shadow_cycles needs a running pipeline (no cycles run now)");
  BlockEntry* incumbent = role->live.load(std::memory_order_acquire);

  auto p = PreparedPtr(new Prepared());
  p->family = &family;
  p->role = role->family_role;
  p->role_entry = role;
  p->expected = incumbent;
  p->shadow_cycles = request.shadow_cycles;
  p->report.block = request.block;
  p->report.old_plugin = incumbent->plugin_name;

  // The plugin: it must load and create a block (not a model, not an io board).
  const std::string plugin = request.plugin.empty() ? incumbent->plugin_name : request.plugin;
  auto loaded = roles_.plugin(plugin);
  if (!loaded) return fail("plugin '" + plugin + "' cannot be used: " + loaded.error());
  if (!creates_block(loaded->descriptor->kind) || loaded->descriptor->kind == PluginKind::io)
    return fail("plugin " + plugin + " is " +
                (loaded->descriptor->kind == PluginKind::io ? std::string("an io board")
                                                            : "a " + std::string(to_string(loaded->descriptor->kind)) + " model") +
                ", not a block that can stand in for " + incumbent->plugin_name);
  // A block of another kind may stand in when its ports fit, but when it does not, that is
  // the likelier mistake (a controller named for an estimator): said first.
  const std::string other_kind =
      incumbent->plugin.descriptor && loaded->descriptor->kind != incumbent->plugin.descriptor->kind
          ? " (" + plugin + " is of kind " + to_string(loaded->descriptor->kind) + "; " + request.block + " runs " +
                incumbent->plugin_name + ", of kind " + to_string(incumbent->plugin.descriptor->kind) + ")"
          : std::string();
  p->report.new_plugin = plugin;

  // Its parameters.
  YAML::Node given;
  try {
    given = request.params.empty() ? YAML::Node(YAML::NodeType::Map) : YAML::Load(request.params);
  } catch (const YAML::Exception& ex) {
    return fail("parameters are not valid YAML: " + ex.msg + " (give a map, e.g. '{d: 0.3}')");
  }
  if (!given.IsMap()) return fail("parameters must be a YAML map, e.g. '{d: 0.3}'");
  YAML::Node node;
  if (plugin == incumbent->plugin_name) {
    node = YAML::Clone(incumbent->node);
    for (const auto& kv : given) node[kv.first.as<std::string>()] = kv.second;
  } else {
    node = YAML::Clone(given);
  }
  node["plugin"] = plugin;
  node.remove("shadow_of");
  node.remove("shadow_decimation");

  auto record = std::make_unique<BlockEntry>();
  record->name = request.block;
  record->plugin_name = plugin;
  record->plugin = *loaded;
  record->node = node;
  record->where = {"swap request", 1, 1};
  record->candidate = true;
  // Its wiring and configuration go through the loader's own code, collecting its
  // diagnostics here.
  Diagnostics diagnostics;
  std::vector<std::string> unused;
  roles_.configure_candidate(*record, given["inputs"], *incumbent, diagnostics, unused);
  if (!unused.empty()) p->report.state_notes.push_back("inputs not used by " + plugin + ": " + join(unused));
  if (!diagnostics.empty()) {
    std::string why;
    for (const auto& d : diagnostics.items()) why += (why.empty() ? "" : "; ") + d.field + ": " + d.message;
    return fail(plugin + " refused its configuration" + other_kind + ": " + why);
  }
  if (!record->block) return fail("plugin " + plugin + " did not create a block");

  // Every input must be computed before this role steps (it takes the role's place in the order).
  if (const InputWiring* stale = roles_.stale_input(*record, family))
    return fail("input '" + stale->input + "' reads " + stale->source + ", which is computed after " + request.block +
                " in the cycle (or is a shadow): it would read a stale value");
  // It must provide every output of the role, same size and units.
  if (const std::string problem = Roles::stand_in_problem(*record, *role); !problem.empty())
    return fail(plugin + " cannot take the place of " + incumbent->plugin_name + other_kind + ": it " + problem +
                " (a replacement must provide every output of the block, same size and units)");

  // Storage, bindings, activation.
  roles_.bind_candidate(*record, family);
  Status activated;
  try {
    activated = record->block->activate();
  } catch (const std::exception& ex) {
    activated = Status::error(std::string("activate() threw: ") + ex.what());
  } catch (...) {
    activated = Status::error("activate() threw");
  }
  if (!activated) return fail(plugin + " failed to activate: " + activated.message());

  // The state handover: newcomer elements matched by name and unit.
  const StateLayout& from = incumbent->layout;
  const StateLayout& to = record->layout;
  if (request.warm_start && !from.empty() && !to.empty()) {
    p->warm = true;
    p->map.assign(to.size(), -1);
    p->present.assign(to.size(), 0);
    std::vector<std::string> mapped, initialised, unit_clash;
    for (std::size_t j = 0; j < to.size(); ++j) {
      for (std::size_t i = 0; i < from.size(); ++i) {
        if (from.elements[i].name != to.elements[j].name) continue;
        if (from.elements[i].unit != to.elements[j].unit) {
          unit_clash.push_back(to.elements[j].name + " (" + from.elements[i].unit + " vs " + to.elements[j].unit + ")");
          break;
        }
        p->map[j] = static_cast<int>(i);
        p->present[j] = 1;
        mapped.push_back(to.elements[j].name);
        break;
      }
      if (!p->present[j]) initialised.push_back(to.elements[j].name);
    }
    std::vector<std::string> dropped;
    for (std::size_t i = 0; i < from.size(); ++i)
      if (std::find(p->map.begin(), p->map.end(), static_cast<int>(i)) == p->map.end())
        dropped.push_back(from.elements[i].name);
    p->report.mapped = mapped.size();
    p->report.initialised = initialised.size();
    p->report.dropped = dropped.size();
    p->report.state_notes.push_back("state handed over: " + std::to_string(mapped.size()) + " of " +
                                    std::to_string(to.size()) + " elements" +
                                    (from.covariance && to.covariance ? " with covariance" : " (no covariance)"));
    if (!initialised.empty())
      p->report.state_notes.push_back("initialised by " + plugin + " (not in " + incumbent->plugin_name + "): " + join(initialised));
    if (!dropped.empty())
      p->report.state_notes.push_back("not used by " + plugin + ": " + join(dropped));
    if (!unit_clash.empty())
      p->report.state_notes.push_back("same name, other unit (initialised instead): " + join(unit_clash));
    p->src_has_cov = from.covariance;
    p->dst_has_cov = to.covariance && from.covariance;
    p->src_values.assign(from.size(), 0.0);
    p->src_cov.assign(from.covariance ? from.size() * from.size() : 1, 0.0);
    p->dst_values.assign(to.size(), 0.0);
    p->dst_cov.assign(to.size() * to.size(), 0.0);
  } else {
    p->report.state_notes.push_back(
        !request.warm_start ? "no state handover (warm_start=false): " + plugin + " starts from its own initial state"
        : from.empty()      ? "no state handover: " + incumbent->plugin_name + " exports no state; " + plugin + " starts from its initial state"
                            : "no state handover: " + plugin + " takes no state; it starts from its initial state");
  }
  // The jump is measured by stepping the retired instance on the exchange cycle's inputs off
  // the RT thread: the RT thread keeps just those (and the role's first output), not the arena.
  p->snapshot.assign(roles_.storage_size(), 0.0);
  for (const auto& w : incumbent->wiring)
    if (const DeclaredOutput* out = roles_.source_of(w)) p->snapshot_spans.push_back({out->offset, out->elements.size()});
  for (const auto& o : role->outputs)
    if (!o.synthetic) {
      p->snapshot_spans.push_back({o.offset, o.elements.size()});
      break;
    }
  p->record = std::move(record);
  p->report.prepare_ns = monotonic_ns() - start;
  return p;
}

}  // namespace lode
