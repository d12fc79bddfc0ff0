// Roles and instances: shadows of a primary, families, the bindings of an instance into a
// role, the exchanges hot swap, promotion and a health fallback make at a cycle boundary, and
// the roles API hot swap uses (roles.hpp).
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
#include "roles.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

std::string Roles::stand_in_problem(const BlockEntry& candidate, const BlockEntry& role) {
  for (const auto& o : role.outputs) {
    if (o.synthetic) continue;
    const DeclaredOutput* mine = candidate.output(o.name);
    if (!mine) return "has no output '" + o.name + "'";
    if (mine->elements.size() != o.elements.size())
      return "has " + std::to_string(mine->elements.size()) + " elements in output '" + o.name + "', " + role.name +
             "." + o.name + " has " + std::to_string(o.elements.size());
    for (std::size_t i = 0; i < o.elements.size(); ++i)
      if (!units_compatible(mine->elements[i].unit, o.elements[i].unit) ||
          !units_compatible(o.elements[i].unit, mine->elements[i].unit))
        return "has output '" + o.name + "." + mine->elements[i].name + "' in '" + mine->elements[i].unit + "', " +
               role.name + "." + o.name + "." + o.elements[i].name + " in '" + o.elements[i].unit + "'";
  }
  return {};
}

void Pipeline::Impl::check_shadows(const std::vector<BlockEntry*>& order) {
  for (auto* b : order) {
    if (b->shadow_of.empty() || !b->block) continue;
    const std::string path = "blocks." + b->name + ".shadow_of";
    BlockEntry* primary = find_block(b->shadow_of);
    if (!primary || !primary->block) continue;  // reported already
    // A shadow must be able to take its primary's place (promotion, fallback): every output
    // of the primary, with the same elements.
    if (const std::string problem = Roles::stand_in_problem(*b, *primary); !problem.empty())
      error(b->shadow_where, path,
            "shadow '" + b->name + "' (" + b->plugin_name + ") cannot stand in for '" + b->shadow_of + "' (" +
                primary->plugin_name + "): it " + problem +
                " (a shadow must provide every output of its primary, same size and units)");
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
  record.layout = record.estimator ? record.estimator->state_layout() : StateLayout{};
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
      slot.estimator = role->estimator;
      slot.role = role;
      slot.decimation = role->shadow_decimation;
      const DeclaredOutput& first = primary->outputs.front();
      slot.primary = arena.data() + first.offset;
      slot.mine = arena.data() + output_offset(*role, first.name);
      slot.disagreement = arena.data() + output_offset(*role, kDisagreementPort);
      slot.disagreement_size = first.elements.size();
      slot.nis = arena.data() + output_offset(*role, kNisPort);
      slot.nu.assign(std::max<std::size_t>(1, role->estimator ? role->estimator->innovation_size() : 0), 0.0);
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

void Pipeline::Impl::put_instance(Family& f, int role, BlockEntry& record) noexcept {
  if (role == 0) {
    ops[f.op].block = record.block.get();
    return;
  }
  ShadowSlot& slot = f.shadows[static_cast<std::size_t>(role - 1)];
  slot.block = record.block.get();
  slot.estimator = record.estimator;
}

void Pipeline::Impl::exchange_roles(Family& f, int role_a, int role_b) noexcept {
  BlockEntry* a = f.roles[static_cast<std::size_t>(role_a)]->live.load(std::memory_order_relaxed);
  BlockEntry* b = f.roles[static_cast<std::size_t>(role_b)]->live.load(std::memory_order_relaxed);
  for (const auto& bind : a->plans[static_cast<std::size_t>(role_b)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  for (const auto& bind : b->plans[static_cast<std::size_t>(role_a)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  auto set_instance = [&](int role, BlockEntry* record) {
    put_instance(f, role, *record);
    f.roles[static_cast<std::size_t>(role)]->live.store(record, std::memory_order_release);
  };
  set_instance(role_a, b);
  set_instance(role_b, a);
}

BlockEntry* Pipeline::Impl::install(Family& f, int role, BlockEntry& record) noexcept {
  BlockEntry* old = f.roles[static_cast<std::size_t>(role)]->live.load(std::memory_order_relaxed);
  for (const auto& bind : old->staging_plan) PortBinder::bind(*bind.port, bind.data, bind.size);
  for (const auto& bind : record.plans[static_cast<std::size_t>(role)]) PortBinder::bind(*bind.port, bind.data, bind.size);
  put_instance(f, role, record);
  f.roles[static_cast<std::size_t>(role)]->live.store(&record, std::memory_order_release);
  return old;
}


}  // namespace lode

// ------------------------------------------------------------------------------------------
// The roles API (hot swap).

namespace lode::pipeline_detail {

BlockEntry* Roles::find(const std::string& name) const { return pipeline_.find_block(name); }

Family& Roles::family_of(const BlockEntry& role) const {
  return pipeline_.families[static_cast<std::size_t>(role.family)];
}

std::vector<std::string> Roles::swappable() const {
  std::vector<std::string> names;
  for (const auto& f : pipeline_.families)
    for (const auto* r : f.roles) names.push_back(r->name);
  return names;
}

Expected<LoadedPlugin> Roles::plugin(const std::string& name) const { return pipeline_.registry->find(name); }

std::size_t Roles::storage_size() const { return pipeline_.arena.size(); }

const double* Roles::storage() const { return pipeline_.arena.data(); }

const DeclaredOutput* Roles::source_of(const InputWiring& wiring) const {
  const BlockEntry* src = pipeline_.find_block(wiring.src_block);
  return src ? src->output(wiring.src_port) : nullptr;
}

void Roles::configure_candidate(BlockEntry& candidate, const YAML::Node& inputs, const BlockEntry& incumbent,
                                Diagnostics& diagnostics, std::vector<std::string>& unused) {
  // The loader reports into the pipeline's diagnostics, located in its file: point both at
  // the request for the time of this call.
  Diagnostics* saved = pipeline_.diag;
  const std::string saved_file = pipeline_.file;
  pipeline_.diag = &diagnostics;
  pipeline_.file = "swap request";
  if (inputs) pipeline_.parse_wiring(inputs, "params", candidate);
  else candidate.wiring = incumbent.wiring;
  if (diagnostics.empty()) pipeline_.configure_block(candidate);
  if (diagnostics.empty()) {
    // Inputs it does not declare are dropped; what it declares must be wired and match.
    std::vector<InputWiring> kept;
    for (auto& w : candidate.wiring) {
      const bool declared = std::any_of(candidate.inputs.begin(), candidate.inputs.end(),
                                        [&](const DeclaredInput& d) { return d.name == w.input; });
      if (declared) kept.push_back(w);
      else unused.push_back(w.input + " (" + w.source + ")");
    }
    candidate.wiring = std::move(kept);
    pipeline_.resolve_inputs_of(candidate);
  }
  pipeline_.diag = saved;
  pipeline_.file = saved_file;
}

const InputWiring* Roles::stale_input(const BlockEntry& candidate, const Family& family) const {
  const auto& ops = pipeline_.ops;
  for (const auto& w : candidate.wiring) {
    const BlockEntry* src = pipeline_.find_block(w.src_block);
    if (!src || src->is_io()) continue;
    std::size_t src_op = ops.size();
    for (std::size_t i = 0; i < ops.size(); ++i)
      if (!ops[i].write_phase && src->family >= 0 && src->family_role == 0 &&
          pipeline_.families[static_cast<std::size_t>(src->family)].op == i)
        src_op = i;
    if (src_op >= family.op) return &w;
  }
  return nullptr;
}

void Roles::bind_candidate(BlockEntry& candidate, const Family& family) {
  pipeline_.prepare_record(candidate, family);
  for (const auto& b : candidate.staging_plan) PortBinder::bind(*b.port, b.data, b.size);
  pipeline_.bind_inputs(candidate, pipeline_.arena.data());
}

BlockEntry* Roles::install(Family& family, int role, BlockEntry& record) noexcept {
  return pipeline_.install(family, role, record);
}

void Roles::exchange(Family& family, int role_a, int role_b) noexcept { pipeline_.exchange_roles(family, role_a, role_b); }

void Roles::set_warming(Family& family, Block* candidate, std::uint32_t cycles) noexcept {
  family.warming = candidate;
  family.warming_left = cycles;
  pipeline_.refresh_watched();
}

void Roles::bind_inputs_to(BlockEntry& record, const double* storage) const { pipeline_.bind_inputs(record, storage); }

void Roles::retire(BlockEntry& record) {
  if (record.block) record.block->deactivate();
  if (record.candidate) {
    auto& pool = pipeline_.pool;
    auto it = std::find_if(pool.begin(), pool.end(), [&](const auto& c) { return c.get() == &record; });
    if (it != pool.end()) pool.erase(it);
    return;
  }
  record.adopt(nullptr);  // the role keeps its storage; its first instance is gone
  record.plans.clear();
  record.staging_plan.clear();
  record.inputs.clear();
  for (auto& o : record.outputs) o.port = nullptr;
}

void Roles::keep(std::unique_ptr<BlockEntry> record) { pipeline_.pool.push_back(std::move(record)); }

}  // namespace lode::pipeline_detail
