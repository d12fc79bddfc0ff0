// A loaded pipeline: its signals and accessors, activation, and the cycle itself.
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
pipeline_detail::Roles& Pipeline::roles() { return impl_->roles; }
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

Status Pipeline::activate() {
  std::fill(impl_->arena.begin(), impl_->arena.end(), 0.0);
  impl_->envelope.reset();
  std::vector<BlockEntry*> activated;
  for (auto* b : impl_->instances()) {
    Status st;
    try {
      st = b->block->activate();
    } catch (const std::exception& ex) {
      st = Status::error(std::string("activate() threw: ") + ex.what());
    }
    if (!st) {
      // Nothing starts half-configured: undo what was activated.
      for (auto* a : activated)
        if (a->board) a->board->drive_safe();
      for (auto* a : activated) a->block->deactivate();
      return Status::error("block '" + b->name + "' failed to activate: " + st.message());
    }
    activated.push_back(b);
  }
  for (auto& f : impl_->families) {
    f.fallback_used = false;
    f.restart_health();
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
    if (b->board) b->board->drive_safe();
}

std::string Pipeline::envelope_violation() const { return impl_->envelope.violation_text(); }

std::vector<Pipeline::EnvelopeBounds> Pipeline::envelope_bounds() const {
  std::vector<EnvelopeBounds> out;
  for (const auto& limit : impl_->envelope.limits())
    if (auto ref = signal(limit.signal)) out.push_back({std::move(*ref), limit.min, limit.max});
  return out;
}

namespace {
/// An op with something around its step: timed (op statistics, a step budget) or watched
/// (health monitor, shadows, a warming candidate). Out of line: most ops of most cycles are not.
/// `clock_ns`: the clock as the previous op's timing left it (-1: not read since), which is
/// this op's start when nothing ran in between. On the real clock every op of every cycle is
/// timed, and a clock read costs tens of nanoseconds (about 50 ns on a KVM guest): one read
/// per op instead of two took a third off a kawato_planar cycle.
[[gnu::noinline]] StepStatus run_watched(Pipeline::Impl& impl, Pipeline::Op& op, const Tick& tick, bool time_ops,
                                         const char*& reason, std::int64_t& clock_ns) noexcept {
  pipeline_detail::Family* family =
      op.family >= 0 ? &impl.families[static_cast<std::size_t>(op.family)] : nullptr;
  const bool timed = time_ops || (family && family->health.step_budget_ns > 0);
  const std::int64_t start = timed ? (clock_ns >= 0 ? clock_ns : monotonic_ns()) : 0;
  StepStatus s = op.write_phase ? op.board->write(tick) : op.block->step(tick);
  const std::int64_t end = timed ? monotonic_ns() : 0;
  const std::int64_t elapsed = end - start;
  clock_ns = timed ? end : -1;
  if (time_ops) op.exec_time->record(elapsed);
  if (family && (family->health.enabled || !family->shadows.empty() || family->warming)) {
    s = impl.after_primary(*family, tick, s, elapsed, reason);
    clock_ns = -1;  // the shadows and the monitor took time of their own: not the next op's
  }
  return s;
}

/// Ops [begin, end) of the cycle; the index of the first that did not return ok (its status in
/// `s`), or `end`. kBare: nothing is timed and no family is watched, each op is just its call.
template <bool kBare>
std::size_t run_ops(Pipeline::Impl& impl, Pipeline::Op* ops, std::size_t begin, std::size_t end, const Tick& tick,
                    bool time_ops, StepStatus& s, const char*& reason) noexcept {
  std::int64_t clock_ns = -1;  // where the previous op's timing read the clock (run_watched)
  for (std::size_t i = begin; i < end; ++i) {
    Pipeline::Op& op = ops[i];
    if (!kBare && (time_ops || (op.family >= 0 && impl.families[static_cast<std::size_t>(op.family)].watched()))) {
      s = run_watched(impl, op, tick, time_ops, reason, clock_ns);
    } else {
      s = op.write_phase ? op.board->write(tick) : op.block->step(tick);
      if (!kBare) clock_ns = -1;
    }
    if (s != StepStatus::ok) return i;
  }
  return end;
}
}  // namespace

Pipeline::CycleResult Pipeline::run_cycle(const Tick& tick, bool time_ops) noexcept {
  // Locals: the blocks' virtual calls could, as far as the compiler knows, change impl_'s
  // members, which would then be reloaded around every op.
  Impl& impl = *impl_;
  Op* const ops = impl.ops.data();
  const std::size_t n = impl.ops.size();
  const bool has_envelope = !impl.envelope.empty();
  // The envelope is checked before op envelope_at (n: after the last op).
  const std::size_t envelope_at = has_envelope ? std::min(impl.envelope_at, n) : n;
  // One flag, read once per cycle: whether any family is watched (a hot swap's warming
  // candidate sets it between cycles, on this thread).
  const bool bare = !time_ops && !impl.watched;
  const auto run = [&](std::size_t begin, std::size_t end, StepStatus& s, const char*& reason) {
    return bare ? run_ops<true>(impl, ops, begin, end, tick, time_ops, s, reason)
                : run_ops<false>(impl, ops, begin, end, tick, time_ops, s, reason);
  };
  StepStatus s = StepStatus::ok;
  const char* reason = nullptr;
  std::size_t failed = run(0, envelope_at, s, reason);
  if (failed == envelope_at && has_envelope && !impl.envelope.check(tick)) {
    drive_safe();
    return {StepStatus::fault, envelope_at < n ? static_cast<int>(envelope_at) : static_cast<int>(n) - 1, nullptr,
            true};
  }
  if (failed == envelope_at) failed = run(envelope_at, n, s, reason);
  if (failed < n) {
    drive_safe();
    return {s, static_cast<int>(failed), reason};
  }
  return {};
}

}  // namespace lode
