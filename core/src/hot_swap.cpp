#include "lode/clock.hpp"
#include "lode/hot_swap.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <thread>

#include "lode/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"

namespace lode {

using namespace pipeline_detail;

namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

std::string join(const std::vector<std::string>& items) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : ", ") + i;
  return s;
}

/// "shadow_cycles=200; warm_start=false" (the `name` field of a swap command).
Status parse_options(const std::string& text, SwapRequest& r) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    auto end = text.find_first_of(";,", pos);
    if (end == std::string::npos) end = text.size();
    std::string item = text.substr(pos, end - pos);
    pos = end + 1;
    item.erase(0, item.find_first_not_of(' '));
    item.erase(item.find_last_not_of(' ') + 1);
    if (item.empty()) continue;
    const auto eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (key == "shadow_cycles") {
      char* e = nullptr;
      const long long n = std::strtoll(value.c_str(), &e, 10);
      if (value.empty() || *e != '\0' || n < 0 || n > 100000000)
        return Status::error("swap option shadow_cycles='" + value + "' must be an integer in 0..100000000");
      r.shadow_cycles = static_cast<std::uint32_t>(n);
    } else if (key == "warm_start") {
      if (value != "true" && value != "false")
        return Status::error("swap option warm_start='" + value + "' must be true or false");
      r.warm_start = value == "true";
    } else {
      return Status::error("unknown swap option '" + key + "' (shadow_cycles=N, warm_start=true|false)");
    }
  }
  return {};
}

}  // namespace

struct HotSwap::Prepared {
  enum class Kind { replace, promote } kind = Kind::replace;
  SwapReport report;
  Family* family = nullptr;
  int role = 0;                       // role index in the family
  BlockEntry* role_entry = nullptr;
  BlockEntry* expected = nullptr;     // the record live in the role when prepared
  std::unique_ptr<BlockEntry> record; // the newcomer (replace)
  int promote_slot = -1;              // promote: the shadow slot
  std::uint32_t shadow_cycles = 0;
  // Warm start: newcomer element j <- incumbent element map[j] (or absent).
  bool warm = false;
  std::vector<int> map;
  std::vector<std::uint8_t> present;
  std::vector<double> src_values, src_cov, dst_values, dst_cov;
  bool src_has_cov = false, dst_has_cov = false;
  // Filled on the RT thread.
  bool refused = false;
  const char* refusal = "";
  std::uint64_t cycle = 0;
  std::int64_t time_ns = 0;
  double dt_s = 0.0;
  std::int64_t cost_ns = 0;
  BlockEntry* retired = nullptr;
  std::vector<double> snapshot;       // arena-shaped: the spans below, at the end of the exchange cycle
  struct Span {
    std::size_t offset = 0, size = 0;
  };
  std::vector<Span> snapshot_spans;   // the retired instance's inputs and the role's first output
  std::int64_t prepared_at_ns = 0;
  bool prefetched = false;            // the RT thread has issued the prefetches (one cycle ahead)
};

void HotSwap::PreparedDeleter::operator()(Prepared* p) const noexcept { delete p; }

HotSwap::HotSwap(Pipeline& pipeline, EventLog& events) : pipeline_(pipeline), events_(events) {}

HotSwap::~HotSwap() = default;

// ------------------------------------------------------------------------------------------
// Off the RT thread: build the newcomer.

Expected<HotSwap::PreparedPtr> HotSwap::prepare(const SwapRequest& request) {
  auto& im = *pipeline_.impl_;
  const std::int64_t start = monotonic_ns();
  auto fail = [&](const std::string& why) {
    return Expected<PreparedPtr>(Status::error("swap " + request.block + ": " + why));
  };
  BlockEntry* role = im.find_block(request.block);
  if (!role || (!role->block && role->live.load() == role)) {
    std::vector<std::string> names;
    for (auto& f : im.families)
      for (auto* r : f.roles) names.push_back(r->name);
    return fail("no swappable block '" + request.block + "' (swappable: " + join(names) + ")");
  }
  if (role->family < 0)
    return fail("'" + request.block + "' is " + (role->is_io() ? "an io block: it owns hardware and is not hot-swappable" : "not swappable"));
  Family& family = im.families[static_cast<std::size_t>(role->family)];
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
  auto loaded = im.registry->find(plugin);
  if (!loaded) return fail("plugin '" + plugin + "' cannot be used: " + loaded.error());
  if (loaded->descriptor->kind != PluginKind::block)
    return fail("plugin " + plugin + " is " +
                (loaded->descriptor->kind == PluginKind::io ? std::string("an io board")
                                                            : "a " + std::string(to_string(loaded->descriptor->kind)) + " model") +
                ", not a block that can stand in for " + incumbent->plugin_name);
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
  if (given["inputs"]) {
    if (!given["inputs"].IsMap()) return fail("`inputs` must be a map input: block.port");
    for (const auto& in : given["inputs"]) {
      InputWiring w;
      w.input = in.first.as<std::string>();
      w.source = in.second.as<std::string>();
      const auto dot = w.source.find('.');
      if (dot == std::string::npos) return fail("inputs." + w.input + ": '" + w.source + "' is not block.port");
      w.src_block = w.source.substr(0, dot);
      w.src_port = w.source.substr(dot + 1);
      record->wiring.push_back(std::move(w));
    }
  } else {
    record->wiring = incumbent->wiring;
  }

  // Configure with the loader's own code path, collecting its diagnostics here.
  Diagnostics diagnostics;
  Diagnostics* saved = im.diag;
  const std::string saved_file = im.file;
  im.diag = &diagnostics;
  im.file = "swap request";
  im.configure_block(*record);
  if (diagnostics.empty()) {
    // Inputs it does not declare are dropped; what it declares must be wired and match.
    std::vector<std::string> dropped;
    std::vector<InputWiring> kept;
    for (auto& w : record->wiring) {
      const bool declared = std::any_of(record->inputs.begin(), record->inputs.end(),
                                        [&](const DeclaredInput& d) { return d.name == w.input; });
      if (declared) kept.push_back(w);
      else dropped.push_back(w.input + " (" + w.source + ")");
    }
    record->wiring = std::move(kept);
    if (!dropped.empty()) p->report.state_notes.push_back("inputs not used by " + plugin + ": " + join(dropped));
    im.resolve_inputs_of(*record);
  }
  im.diag = saved;
  im.file = saved_file;
  if (!diagnostics.empty()) {
    std::string why;
    for (const auto& d : diagnostics.items()) why += (why.empty() ? "" : "; ") + d.field + ": " + d.message;
    return fail(plugin + " refused its configuration: " + why);
  }
  if (!record->block) return fail("plugin " + plugin + " did not create a block");

  // Every input must be computed before this role steps (it takes the role's place in the order).
  const std::size_t role_op = family.op;
  for (const auto& w : record->wiring) {
    const BlockEntry* src = im.find_block(w.src_block);
    if (!src || src->is_io()) continue;
    std::size_t src_op = im.ops.size();
    for (std::size_t i = 0; i < im.ops.size(); ++i)
      if (!im.ops[i].write_phase && src->family >= 0 && src->family_role == 0 &&
          im.families[static_cast<std::size_t>(src->family)].op == i)
        src_op = i;
    if (src_op >= role_op)
      return fail("input '" + w.input + "' reads " + w.source + ", which is computed after " + request.block +
                  " in the cycle (or is a shadow): it would read a stale value");
  }
  // It must provide every output of the role, same size and units.
  for (const auto& o : role->outputs) {
    if (o.synthetic) continue;
    const DeclaredOutput* mine = record->output(o.name);
    std::string problem;
    if (!mine) problem = "has no output '" + o.name + "'";
    else if (mine->elements.size() != o.elements.size())
      problem = "output '" + o.name + "' has " + std::to_string(mine->elements.size()) + " elements, the role has " +
                std::to_string(o.elements.size());
    else
      for (std::size_t i = 0; i < o.elements.size() && problem.empty(); ++i)
        if (!units_compatible(mine->elements[i].unit, o.elements[i].unit) ||
            !units_compatible(o.elements[i].unit, mine->elements[i].unit))
          problem = "output '" + o.name + "." + mine->elements[i].name + "' is in '" + mine->elements[i].unit +
                    "', the role's in '" + o.elements[i].unit + "'";
    if (!problem.empty())
      return fail(plugin + " cannot take the place of " + incumbent->plugin_name + ": it " + problem +
                  " (a replacement must provide every output of the block, same size and units)");
  }

  // Storage, bindings, activation.
  im.prepare_record(*record, family);
  for (const auto& b : record->staging_plan) PortBinder::bind(*b.port, b.data, b.size);
  im.bind_inputs(*record);
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
  p->snapshot.assign(im.arena.size(), 0.0);
  for (const auto& w : incumbent->wiring) {
    const BlockEntry* src = im.find_block(w.src_block);
    const DeclaredOutput* out = src ? src->output(w.src_port) : nullptr;
    if (out) p->snapshot_spans.push_back({out->offset, out->elements.size()});
  }
  for (const auto& o : role->outputs)
    if (!o.synthetic) {
      p->snapshot_spans.push_back({o.offset, o.elements.size()});
      break;
    }
  p->record = std::move(record);
  p->report.prepare_ns = monotonic_ns() - start;
  return p;
}

// ------------------------------------------------------------------------------------------
// The RT thread.

void HotSwap::post(Prepared& prepared) {
  box_ = &prepared;
  state_.store(kPosted, std::memory_order_release);
}

bool HotSwap::posted() const { return state_.load(std::memory_order_acquire) != kIdle; }
bool HotSwap::done() const { return state_.load(std::memory_order_acquire) == kDone; }

namespace {
constexpr std::size_t kCacheLine = 64;
/// Non-blocking: the lines arrive while the rest of the cycle runs (and never fault).
void prefetch_bytes(const void* address, std::size_t bytes) noexcept {
  const char* c = static_cast<const char*>(address);
  for (std::size_t i = 0; i < bytes; i += kCacheLine) __builtin_prefetch(c + i, 1, 3);
}
template <typename T>
void prefetch_vector(const std::vector<T>& v) noexcept {
  if (!v.empty()) prefetch_bytes(v.data(), v.size() * sizeof(T));
}
/// Bytes of a block object prefetched (its size is the plugin's business; prefetching past
/// its end is harmless).
constexpr std::size_t kBlockObjectBytes = 512;
}  // namespace

void HotSwap::prefetch(Prepared& p) noexcept {
  // Everything the exchange will touch was written by the preparing thread, on another core:
  // fetched on demand at the exchange it costs a cache miss per line (measured ~2.5 us in all
  // on a 2-vCPU VM). Prefetched one cycle ahead, it is in this core's cache at the exchange.
  prefetch_bytes(&p, sizeof(Prepared));
  prefetch_vector(p.map);
  prefetch_vector(p.present);
  prefetch_vector(p.src_values);
  prefetch_vector(p.src_cov);
  prefetch_vector(p.dst_values);
  prefetch_vector(p.dst_cov);
  prefetch_vector(p.snapshot_spans);
  for (const auto& span : p.snapshot_spans) prefetch_bytes(p.snapshot.data() + span.offset, span.size * sizeof(double));
  if (p.record) {
    prefetch_bytes(p.record.get(), sizeof(BlockEntry));
    prefetch_bytes(p.record->block.get(), kBlockObjectBytes);
    if (static_cast<std::size_t>(p.role) < p.record->plans.size()) {
      const auto& plan = p.record->plans[static_cast<std::size_t>(p.role)];
      prefetch_vector(plan);
      for (const auto& bind : plan) prefetch_bytes(bind.port, sizeof(OutputPort));
    }
  }
  if (p.expected) prefetch_vector(p.expected->staging_plan);
}

void HotSwap::before_cycle(const Tick& tick) noexcept {
  int state = state_.load(std::memory_order_acquire);
  if (state == kPosted) {
    // A posted request may be withdrawn by the caller (timeout): claim it before touching it.
    if (!state_.compare_exchange_strong(state, kClaimed, std::memory_order_acq_rel)) return;
    const std::int64_t t0 = monotonic_ns();
    prefetch(*box_);
    box_->cost_ns += monotonic_ns() - t0;
    state_.store(kPrefetched, std::memory_order_release);
    return;  // the lines arrive while this cycle runs; the exchange is at its end
  }
  if (state != kWarming) return;
  Prepared& p = *box_;  // warming: this thread owns the request until it is installed
  if (p.family->warming_left > 0) return;  // still running as a shadow
  const std::int64_t t0 = monotonic_ns();
  install(p, tick, t0);
}

void HotSwap::after_cycle(const Tick& tick) noexcept {
  int state = state_.load(std::memory_order_acquire);
  if (state == kInstalled) {
    // The end of the newcomer's first cycle: keep the retired instance's inputs of that cycle.
    Prepared& p = *box_;
    const std::int64_t t0 = monotonic_ns();
    const double* arena = pipeline_.impl_->arena.data();
    for (const auto& span : p.snapshot_spans)
      std::memcpy(p.snapshot.data() + span.offset, arena + span.offset, span.size * sizeof(double));
    p.cost_ns += monotonic_ns() - t0;
    state_.store(kDone, std::memory_order_release);
    return;
  }
  if (state != kPrefetched || !state_.compare_exchange_strong(state, kClaimed, std::memory_order_acq_rel)) return;
  // The end of this cycle is the boundary before the next one (nothing runs in between), and
  // the lines prefetched at its start are in this core's cache now: exchange here. (Across
  // the sleep to the next cycle they would not survive on a VM whose idle vCPU loses its cache.)
  Prepared& p = *box_;
  auto& im = *pipeline_.impl_;
  Family& f = *p.family;
  const std::int64_t t0 = monotonic_ns();
  Tick boundary = tick;
  boundary.cycle = tick.cycle + 1;
  boundary.time_ns = tick.time_ns + pipeline_.period_ns();
  if (p.role_entry->live.load(std::memory_order_relaxed) != p.expected) {
    p.refused = true;
    p.refusal = "the block changed (health fallback or promotion) while the swap was prepared; retry";
    state_.store(kDone, std::memory_order_release);
    return;
  }
  if (p.kind == Prepared::Kind::promote) {
    im.exchange_roles(f, 0, p.promote_slot + 1);
    f.fallback_used = false;  // the user chose: the fallback is armed again
    // The health statistics were the old primary's: the promoted block starts its own (as
    // after a fallback or a swap), or its first slow step would trip on the old one's.
    f.restart_health();
    p.cycle = boundary.cycle;
    p.time_ns = boundary.time_ns;
    p.cost_ns += monotonic_ns() - t0;
    state_.store(kDone, std::memory_order_release);
    return;
  }
  if (p.warm) {
    Block* incumbent = p.role == 0 ? im.ops[f.op].block : f.shadows[static_cast<std::size_t>(p.role - 1)].block;
    incumbent->export_state(p.src_values.data(), p.src_has_cov ? p.src_cov.data() : nullptr);
    const std::size_t n_to = p.dst_values.size();
    const std::size_t n_from = p.src_values.size();
    for (std::size_t j = 0; j < n_to; ++j) {
      const int i = p.map[j];
      p.dst_values[j] = i >= 0 ? p.src_values[static_cast<std::size_t>(i)] : 0.0;
      if (!p.dst_has_cov) continue;
      for (std::size_t k = 0; k < n_to; ++k) {
        const int l = p.map[k];
        p.dst_cov[j * n_to + k] = (i >= 0 && l >= 0) ? p.src_cov[static_cast<std::size_t>(i) * n_from + static_cast<std::size_t>(l)] : 0.0;
      }
    }
    p.record->block->import_state(p.dst_values.data(), p.dst_has_cov ? p.dst_cov.data() : nullptr, p.present.data());
  }
  if (p.shadow_cycles > 0) {
    f.warming = p.record->block.get();
    f.warming_left = p.shadow_cycles;
    p.cost_ns += monotonic_ns() - t0;
    state_.store(kWarming, std::memory_order_release);
    return;
  }
  install(p, boundary, t0);
}

void HotSwap::install(Prepared& p, const Tick& boundary, std::int64_t t0) noexcept {
  auto& im = *pipeline_.impl_;
  Family& f = *p.family;
  p.retired = im.install(f, p.role, *p.record);
  f.warming = nullptr;
  if (p.role == 0) {
    f.restart_health();
  }
  p.cycle = boundary.cycle;
  p.time_ns = boundary.time_ns;
  p.dt_s = boundary.dt_s;
  p.cost_ns += monotonic_ns() - t0;
  state_.store(kInstalled, std::memory_order_release);
}

// ------------------------------------------------------------------------------------------
// Off the RT thread again: measure the jump, retire the old instance, report.

SwapReport HotSwap::finish(PreparedPtr prepared) {
  Prepared& p = *prepared;
  auto& im = *pipeline_.impl_;
  state_.store(kIdle, std::memory_order_release);
  box_ = nullptr;
  SwapReport report = std::move(p.report);
  report.cycle = p.cycle;
  report.time_ns = p.time_ns;
  report.rt_cost_ns = p.cost_ns;
  if (!p.refused) rt_cost_.record(p.cost_ns);  // here, not on the RT thread: its bins are cold there
  if (p.refused) {
    report.ok = false;
    report.message = "swap " + report.block + ": not done: " + p.refusal + "; " + report.old_plugin + " keeps running";
    if (p.record && p.record->block) p.record->block->deactivate();
    events_.post_limited(p.time_ns, p.cycle, "command_failed", report.message);
    return report;
  }
  if (p.kind == Prepared::Kind::promote) {
    ++swaps_;
    swap_cycles_.push_back(p.cycle);
    report.ok = true;
    report.message = "promoted " + report.block + " at cycle " + std::to_string(p.cycle) + ": " +
                     p.family->primary->name + " now runs " + pipeline_.plugin_of(p.family->primary->name) + ", " +
                     report.block + " runs " + pipeline_.plugin_of(report.block) + " (RT cost " +
                     std::to_string(p.cost_ns) + " ns)";
    events_.post(p.time_ns, p.cycle, "swap", report.message);
    return report;
  }
  BlockEntry* retired = p.retired;
  // The jump: step the retired instance once more on the exchange cycle's inputs (taken from
  // the snapshot), into its staging storage, and compare with the newcomer's output.
  const DeclaredOutput* first = nullptr;
  for (const auto& o : p.role_entry->outputs)
    if (!o.synthetic) { first = &o; break; }
  if (retired && retired->block && first && running_.load(std::memory_order_acquire)) {
    for (auto& d : retired->inputs)
      for (const auto& w : retired->wiring) {
        if (w.input != d.name) continue;
        const BlockEntry* src = im.find_block(w.src_block);
        const DeclaredOutput* out = src ? src->output(w.src_port) : nullptr;
        if (out) PortBinder::bind(*d.port, p.snapshot.data() + out->offset, out->elements.size());
      }
    Tick tick;
    tick.cycle = p.cycle;
    tick.time_ns = p.time_ns;
    tick.dt_s = p.dt_s;
    const DeclaredOutput* theirs = retired->output(first->name);
    report.jump_port = first->name;
    report.jump_elements = first->elements;
    if (retired->block->step(tick) == StepStatus::ok && theirs) {
      for (std::size_t i = 0; i < first->elements.size(); ++i)
        report.jump.push_back(p.snapshot[first->offset + i] - retired->staging[theirs->offset + i]);
    } else {
      report.state_notes.push_back(std::string("jump not measured: the retired instance faulted on the exchange cycle's inputs (") +
                                   retired->block->fault_reason() + ")");
    }
  }
  // Retire: deactivate and destroy off the RT thread; the newcomer joins the pool.
  if (retired && retired->block) {
    retired->block->deactivate();
    if (retired->candidate) {
      auto it = std::find_if(im.pool.begin(), im.pool.end(), [&](const auto& c) { return c.get() == retired; });
      if (it != im.pool.end()) im.pool.erase(it);
    } else {
      retired->block.reset();  // the role keeps its storage; its first instance is gone
      retired->plans.clear();
      retired->staging_plan.clear();
      retired->inputs.clear();
      for (auto& o : retired->outputs) o.port = nullptr;
    }
  }
  im.pool.push_back(std::move(p.record));
  ++swaps_;
  swap_cycles_.push_back(p.cycle);

  report.ok = true;
  std::string jump_text;
  if (!report.jump.empty()) {
    for (std::size_t i = 0; i < report.jump.size(); ++i)
      jump_text += (i ? ", " : "") + report.jump_elements[i].name + " " + number(report.jump[i]) +
                   (report.jump_elements[i].unit.empty() ? "" : " " + report.jump_elements[i].unit);
    jump_text = "; jump of " + report.block + "." + report.jump_port + ": " + jump_text;
  }
  report.message = "swapped " + report.block + ": " + report.old_plugin + " -> " + report.new_plugin + " at cycle " +
                   std::to_string(report.cycle) + " (" + join(report.state_notes) + jump_text + "; RT cost " +
                   std::to_string(report.rt_cost_ns) + " ns, prepared in " + number(report.prepare_ns * 1e-6) + " ms)";
  events_.post(report.time_ns, report.cycle, "swap", report.message);
  return report;
}

SwapReport HotSwap::wait_and_finish(PreparedPtr prepared, std::chrono::milliseconds timeout) {
  if (!running_.load(std::memory_order_acquire)) {
    // No RT thread: this thread owns the blocks. Same code path, at "cycle 0".
    post(*prepared);
    Tick idle;
    idle.dt_s = 1.0 / pipeline_.rate_hz();
    while (!done()) {  // prefetch, then exchange (shadow_cycles is 0 here)
      before_cycle(idle);
      after_cycle(idle);
    }
    return finish(std::move(prepared));
  }
  post(*prepared);
  const auto deadline = std::chrono::steady_clock::now() + timeout +
                        std::chrono::milliseconds(static_cast<std::int64_t>(
                            1e3 * prepared->shadow_cycles / pipeline_.rate_hz()));
  while (!done()) {
    const bool stopped = !running_.load(std::memory_order_acquire);
    if (stopped || std::chrono::steady_clock::now() > deadline) {
      int posted = kPosted, prefetched = kPrefetched;
      if (state_.compare_exchange_strong(posted, kIdle, std::memory_order_acq_rel) ||
          state_.compare_exchange_strong(prefetched, kIdle, std::memory_order_acq_rel)) {
        SwapReport r = std::move(prepared->report);
        r.ok = false;
        r.message = "swap " + r.block + ": not done: " +
                    (stopped ? std::string("the pipeline stopped before the exchange")
                             : std::string("the pipeline did not reach a cycle boundary in time")) +
                    "; " + r.old_plugin + " keeps running";
        box_ = nullptr;
        if (prepared->record && prepared->record->block) prepared->record->block->deactivate();
        return r;
      }
      if (stopped) {
        // Warming or installed when the RT thread stopped (it has been joined): complete the
        // exchange on this thread, as when no RT thread runs.
        const int state = state_.load(std::memory_order_acquire);
        if (state == kWarming || state == kInstalled) {
          if (state == kWarming) prepared->family->warming_left = 0;
          Tick idle;
          idle.dt_s = 1.0 / pipeline_.rate_hz();
          before_cycle(idle);
          after_cycle(idle);
          continue;
        }
      }
      // Otherwise warming or installed: the RT thread holds it; it finishes within cycles.
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  return finish(std::move(prepared));
}

SwapReport HotSwap::swap(const SwapRequest& request, std::chrono::milliseconds timeout) {
  std::lock_guard lock(mutex_);
  auto prepared = prepare(request);
  if (!prepared) {
    SwapReport r;
    r.block = request.block;
    r.ok = false;
    r.message = prepared.error() + "; the running block is unchanged";
    events_.post_limited(0, 0, "command_failed", r.message + (request.client.empty() ? "" : " (by " + request.client + ")"));
    return r;
  }
  return wait_and_finish(std::move(*prepared), timeout);
}

SwapReport HotSwap::promote(const std::string& shadow, std::chrono::milliseconds timeout) {
  std::lock_guard lock(mutex_);
  auto& im = *pipeline_.impl_;
  SwapReport r;
  r.block = shadow;
  BlockEntry* role = im.find_block(shadow);
  if (!role || role->shadow_of.empty() || role->family < 0) {
    std::vector<std::string> names;
    for (const auto& s : pipeline_.shadows()) names.push_back(s.name);
    r.message = "promote: '" + shadow + "' is not a shadow" + (names.empty() ? " (this pipeline has none)" : " (shadows: " + join(names) + ")");
    events_.post_limited(0, 0, "command_failed", r.message);
    return r;
  }
  auto p = PreparedPtr(new Prepared());
  p->kind = Prepared::Kind::promote;
  p->family = &im.families[static_cast<std::size_t>(role->family)];
  p->role = role->family_role;
  p->role_entry = role;
  p->expected = role->live.load(std::memory_order_acquire);
  p->promote_slot = role->family_role - 1;
  p->report.block = shadow;
  p->report.old_plugin = pipeline_.plugin_of(p->family->primary->name);
  p->report.new_plugin = pipeline_.plugin_of(shadow);
  return wait_and_finish(std::move(p), timeout);
}

ControlReply HotSwap::handle(const ControlRequest& request) {
  ControlReply reply;
  reply.id = request.id;
  SwapReport report;
  if (request.kind == "promote" || request.value == "promote") {
    report = promote(request.kind == "promote" && !request.block.empty() ? request.block : request.name);
  } else {
    SwapRequest s;
    s.block = request.block;
    s.plugin = request.plugin;
    s.params = request.value;
    s.client = request.client;
    if (auto st = parse_options(request.name, s); !st) {
      reply.ok = false;
      reply.message = "swap " + request.block + ": " + st.message();
      return reply;
    }
    report = swap(s);
  }
  reply.ok = report.ok;
  reply.message = report.message;
  reply.value = report.new_plugin;
  return reply;
}

std::size_t HotSwap::poll_events() {
  std::size_t n = 0;
  for (const auto& t : pipeline_.take_health_trips()) {
    if (t.lost > 0) {
      events_.post(0, 0, "warning", std::to_string(t.lost) + " health-monitor trips were lost (ring full)");
    } else if (!t.fallback.empty()) {
      events_.post(t.time_ns, t.cycle, "health",
                   "health monitor: " + t.block + " tripped at cycle " + std::to_string(t.cycle) + " (" + t.reason +
                       "); fallback " + t.fallback + " took over in the same cycle: " + t.block + " now runs " +
                       t.fallback_plugin + ", the tripped instance runs on as shadow " + t.fallback);
    } else {
      events_.post(t.time_ns, t.cycle, "health",
                   "health monitor: " + t.block + " tripped at cycle " + std::to_string(t.cycle) + " (" + t.reason +
                       "); no fallback armed: outputs driven safe");
    }
    ++n;
  }
  return n;
}

}  // namespace lode
