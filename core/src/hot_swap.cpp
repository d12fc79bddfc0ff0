#include "lode/sdk/clock.hpp"
#include "lode/hot_swap.hpp"
#include "lode/sdk/rt_log.hpp"

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

void HotSwap::PreparedDeleter::operator()(Prepared* p) const noexcept { delete p; }

HotSwap::HotSwap(Pipeline& pipeline, EventLog& events)
    : pipeline_(pipeline), roles_(pipeline.roles()), events_(events) {}

HotSwap::~HotSwap() = default;

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
    const double* arena = roles_.storage();
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
    roles_.exchange(f, 0, p.promote_slot + 1);
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
    // Warm starts are prepared only between two estimators with state (both layouts non-empty).
    EstimatorState* incumbent = f.roles[static_cast<std::size_t>(p.role)]->live.load(std::memory_order_relaxed)->estimator;
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
    p.record->estimator->import_state(p.dst_values.data(), p.dst_has_cov ? p.dst_cov.data() : nullptr, p.present.data());
  }
  if (p.shadow_cycles > 0) {
    roles_.set_warming(f, p.record->block.get(), p.shadow_cycles);
    p.cost_ns += monotonic_ns() - t0;
    state_.store(kWarming, std::memory_order_release);
    return;
  }
  install(p, boundary, t0);
}

void HotSwap::install(Prepared& p, const Tick& boundary, std::int64_t t0) noexcept {
  Family& f = *p.family;
  p.retired = roles_.install(f, p.role, *p.record);
  roles_.set_warming(f, nullptr, f.warming_left);
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
    roles_.bind_inputs_to(*retired, p.snapshot.data());
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
  if (retired && retired->block) roles_.retire(*retired);
  roles_.keep(std::move(p.record));
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

SwapReport HotSwap::wait_and_finish(PreparedPtr prepared, std::chrono::milliseconds timeout,
                                    std::unique_lock<std::mutex>* released_while_shadowing) {
  // Held again on every way out, before anything the caller's lock guards is touched.
  struct Reacquire {
    std::unique_lock<std::mutex>* lock;
    std::atomic<bool>& shadowing;
    void operator()() const {
      if (lock != nullptr && !lock->owns_lock()) {
        lock->lock();
        shadowing.store(false, std::memory_order_release);
      }
    }
    ~Reacquire() { (*this)(); }
  } reacquire{released_while_shadowing, shadowing_};
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
    // The shadow period: nothing to do here but wait, so the caller's commands go on.
    if (released_while_shadowing != nullptr && released_while_shadowing->owns_lock() &&
        state_.load(std::memory_order_acquire) == kWarming) {
      shadowing_block_ = prepared->report.block;
      shadowing_.store(true, std::memory_order_release);
      released_while_shadowing->unlock();
    }
    const bool stopped = !running_.load(std::memory_order_acquire);
    if (stopped || std::chrono::steady_clock::now() > deadline) {
      int posted = kPosted, prefetched = kPrefetched;
      reacquire();
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
  reacquire();
  return finish(std::move(prepared));
}

SwapReport HotSwap::swap(const SwapRequest& request, std::chrono::milliseconds timeout,
                         std::unique_lock<std::mutex>* released_while_shadowing) {
  std::lock_guard lock(mutex_);
  // Off the RT thread, on the command path: whatever a plugin or a parameter text throws
  // while the newcomer is prepared is a refusal, never an exception out of the command
  // thread (that would end the run).
  Expected<PreparedPtr> prepared = Status::error("");
  try {
    prepared = prepare(request);
  } catch (const std::exception& ex) {
    prepared = Status::error(std::string("preparing the swap failed: ") + ex.what());
  } catch (...) {
    prepared = Status::error("preparing the swap failed (unknown exception)");
  }
  if (!prepared) {
    SwapReport r;
    r.block = request.block;
    r.ok = false;
    r.message = prepared.error() + "; the running block is unchanged";
    std::int64_t time_ns = 0;
    std::uint64_t cycle = 0;
    rt_log_clock(time_ns, cycle);  // refused before it reached the RT thread: the cycle running now
    events_.post_limited(time_ns, cycle, "command_failed", r.message + (request.client.empty() ? "" : " (by " + request.client + ")"));
    return r;
  }
  return wait_and_finish(std::move(*prepared), timeout, released_while_shadowing);
}

SwapReport HotSwap::promote(const std::string& shadow, std::chrono::milliseconds timeout) {
  std::lock_guard lock(mutex_);
  SwapReport r;
  r.block = shadow;
  BlockEntry* role = roles_.find(shadow);
  if (!role || role->shadow_of.empty() || role->family < 0) {
    std::vector<std::string> names;
    for (const auto& s : pipeline_.shadows()) names.push_back(s.name);
    r.message = "promote: '" + shadow + "' is not a shadow" + (names.empty() ? " (this pipeline has none)" : " (shadows: " + join(names) + ")");
    std::int64_t time_ns = 0;
    std::uint64_t cycle = 0;
    rt_log_clock(time_ns, cycle);
    events_.post_limited(time_ns, cycle, "command_failed", r.message);
    return r;
  }
  auto p = PreparedPtr(new Prepared());
  p->kind = Prepared::Kind::promote;
  p->family = &roles_.family_of(*role);
  p->role = role->family_role;
  p->role_entry = role;
  p->expected = role->live.load(std::memory_order_acquire);
  p->promote_slot = role->family_role - 1;
  p->report.block = shadow;
  p->report.old_plugin = pipeline_.plugin_of(p->family->primary->name);
  p->report.new_plugin = pipeline_.plugin_of(shadow);
  return wait_and_finish(std::move(p), timeout);
}

ControlRequest swap_command(const SwapRequest& request) {
  ControlRequest r;
  r.kind = "swap";
  r.block = request.block;
  r.plugin = request.plugin;
  r.value = request.params;
  r.client = request.client;
  if (request.shadow_cycles > 0) r.name = "shadow_cycles=" + std::to_string(request.shadow_cycles);
  if (!request.warm_start) r.name += std::string(r.name.empty() ? "" : ";") + "warm_start=false";
  return r;
}

ControlRequest promote_command(const std::string& shadow) {
  ControlRequest r;
  r.kind = "swap";
  r.name = shadow;
  r.value = "promote";
  return r;
}

ControlReply HotSwap::handle(const ControlRequest& request, std::unique_lock<std::mutex>* commands) {
  ControlReply reply;
  reply.id = request.id;
  if (shadowing_.load(std::memory_order_acquire)) {
    // An earlier swap waits, without the command lock, for its shadow period to end: this
    // one would wait for it here while holding that lock, which the earlier one needs back.
    reply.ok = false;
    reply.message = "swap: the newcomer for " + shadowing_block_ +
                    " still runs as a shadow (an earlier `lode swap --shadow-cycles`); try again once it has taken over";
    return reply;
  }
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
    report = swap(s, std::chrono::milliseconds(5000), commands);
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
