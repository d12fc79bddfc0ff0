// Hot swap of a running block: replace an estimator while the stage
// runs, promote a shadow, and report health-monitor fallbacks.
//
// Everything that can fail or allocate happens off the RT thread: load the plugin, configure
// the newcomer with the incumbent's wiring, check that it provides every output of the role
// with the same size and units, bind it to private (staging) storage, activate it, and map
// the incumbent's exported state (StateLayout) onto the newcomer's by element name and unit.
// The RT thread prefetches, at the start of a cycle, every cache line the exchange will touch
// (the preparing thread wrote them on another core: fetched on demand they would cost a miss
// each, ~2.5 us in all on the build VM), and at the end of that cycle (after_cycle, the
// boundary before the next; nothing runs in between) does:
//
//   incumbent.export_state -> mapped copy -> newcomer.import_state   (warm start)
//   newcomer's ports -> the role's storage; incumbent's -> its staging; op's Block* = newcomer
//
// which is a few hundred pointer and double writes. Optionally the newcomer first runs as a
// shadow for N cycles on the same inputs (warm-started at the first of them) and takes over
// at the boundary after. At the end of the exchange cycle (after_cycle) the retired
// instance's inputs are copied once, so that off the RT thread it can be stepped on exactly
// that cycle's inputs: the difference between the newcomer's output and what the incumbent would have
// output is the swap's *jump*, reported with every swap. The retired instance is then
// deactivated and destroyed off the RT thread. A swap that fails at any step leaves the
// incumbent running and says why.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "lode/control.hpp"
#include "lode/event_log.hpp"
#include "lode/sdk/histogram.hpp"
#include "lode/pipeline.hpp"
#include "lode/sdk/status.hpp"
#include "lode/telemetry.hpp"

namespace lode {

struct SwapRequest {
  std::string block;   ///< the role to put the newcomer in (a primary or a shadow)
  std::string plugin;  ///< "" = the plugin now running in the role
  /// YAML map of parameters. Same plugin: overrides on the running instance's parameters.
  /// Another plugin: all of its parameters. `inputs:` may re-wire; by default the role's
  /// wiring is kept (inputs the newcomer does not declare are dropped and reported).
  std::string params;
  std::uint32_t shadow_cycles = 0;  ///< run as a shadow this many cycles before taking over
  bool warm_start = true;           ///< hand the incumbent's state over
  std::string client;               ///< who asked (event log)
};

/// The command that asks a running pipeline for `request` (what `lode swap`, `lode scope` and
/// any other client send; HotSwap::handle() reads it back): the options travel in the name
/// field as "shadow_cycles=N;warm_start=false".
ControlRequest swap_command(const SwapRequest& request);
/// The command that promotes `shadow` into its primary's place: a swap whose value says
/// "promote".
ControlRequest promote_command(const std::string& shadow);

struct SwapReport {
  bool ok = false;
  std::string message;  ///< one line: what happened, or precisely why not
  std::string block, old_plugin, new_plugin;
  std::uint64_t cycle = 0;         ///< first cycle whose role outputs came from the newcomer
  std::int64_t time_ns = 0;
  std::vector<std::string> state_notes;  ///< mapped / initialised / dropped elements
  std::size_t mapped = 0, initialised = 0, dropped = 0;
  std::int64_t rt_cost_ns = 0;     ///< RT-thread time of the exchange (both boundary parts)
  std::string jump_port;           ///< the role output the jump is measured on (its first)
  Elements jump_elements;
  std::vector<double> jump;        ///< newcomer's output - incumbent's counterfactual output
  std::int64_t prepare_ns = 0;     ///< off-RT preparation time (load, configure, activate)
};

class HotSwap final : public CycleHook {
 public:
  HotSwap(Pipeline& pipeline, EventLog& events);
  ~HotSwap() override;
  HotSwap(const HotSwap&) = delete;
  HotSwap& operator=(const HotSwap&) = delete;

  /// Whether an RT thread is cycling. When not, the exchange is applied on the calling
  /// thread (no jump is measured and shadow_cycles must be 0).
  void set_running(bool running) { running_.store(running, std::memory_order_release); }

  /// Off the RT thread; serialised. Prepare, hand over at a cycle boundary, wait, finish.
  /// `released_while_shadowing` (a lock the caller holds) is unlocked while the newcomer runs
  /// as a shadow and locked again before the swap finishes.
  SwapReport swap(const SwapRequest& request,
                  std::chrono::milliseconds timeout = std::chrono::milliseconds(5000),
                  std::unique_lock<std::mutex>* released_while_shadowing = nullptr);
  /// Exchange the instances of `shadow`'s role and its primary's at a cycle boundary (both
  /// keep running: the old primary becomes the shadow). Re-arms the health fallback.
  SwapReport promote(const std::string& shadow,
                     std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));
  /// ControlService swap handler: kind "swap" (value "promote" + name = shadow promotes;
  /// name may carry "shadow_cycles=N") and kind "promote". `commands`: the command lock,
  /// released during a shadow period (ControlService::SwapHandler).
  ControlReply handle(const ControlRequest& request, std::unique_lock<std::mutex>* commands = nullptr);

  /// Off the RT thread: post the health monitor's trips (and swaps it caused) as events.
  /// Returns how many were posted. Call from the runner's idle loop.
  std::size_t poll_events();

  /// @name Step by step, for callers that drive the cycles themselves (tests, benchmarks).
  //@{
  struct Prepared;
  /// Prepared is defined in hot_swap.cpp; callers hold it through this handle.
  struct PreparedDeleter {
    void operator()(Prepared* p) const noexcept;
  };
  using PreparedPtr = std::unique_ptr<Prepared, PreparedDeleter>;
  Expected<PreparedPtr> prepare(const SwapRequest& request);
  void post(Prepared& prepared);
  /// A prepared swap is posted and waits for a cycle boundary (or has not been finished yet).
  [[nodiscard]] bool posted() const;
  [[nodiscard]] bool done() const;
  SwapReport finish(PreparedPtr prepared);
  //@}

  void before_cycle(const Tick& tick) noexcept override;
  void after_cycle(const Tick& tick) noexcept override;

  /// RT-thread cost of each exchange (ns), both boundary parts summed.
  [[nodiscard]] const Histogram& rt_cost() const { return rt_cost_; }
  [[nodiscard]] std::uint64_t swaps() const { return swaps_; }
  /// The exchange cycle of every completed swap and promotion (read when no swap is under way).
  [[nodiscard]] const std::vector<std::uint64_t>& swap_cycles() const { return swap_cycles_; }

 private:
  SwapReport wait_and_finish(PreparedPtr prepared, std::chrono::milliseconds timeout,
                             std::unique_lock<std::mutex>* released_while_shadowing = nullptr);
  static void prefetch(Prepared& p) noexcept;
  /// RT thread: the newcomer takes the role from `boundary` on.
  void install(Prepared& p, const Tick& boundary, std::int64_t t0) noexcept;

  Pipeline& pipeline_;
  pipeline_detail::Roles& roles_;  ///< all a swap changes, it changes through this
  EventLog& events_;
  std::mutex mutex_;  ///< serialises swaps; never touched by the RT thread
  /// A swap is in its shadow period with the caller's command lock released (handle());
  /// shadowing_block_ is written before it is set, under that lock.
  std::atomic<bool> shadowing_{false};
  std::string shadowing_block_;
  std::atomic<bool> running_{false};
  Histogram rt_cost_;
  std::uint64_t swaps_ = 0;
  std::vector<std::uint64_t> swap_cycles_;

  // Mailbox: idle -> posted (caller) -> prefetched (RT, cycle start) -> warming/installed (RT, cycle end)
  // -> done (RT) -> idle (caller). The RT thread claims a posted or prefetched request by
  // compare-exchange (to `claimed`) before touching it, so the caller can withdraw it safely.
  enum : int { kIdle = 0, kPosted = 1, kPrefetched = 2, kClaimed = 3, kWarming = 4, kInstalled = 5, kDone = 6 };
  alignas(64) std::atomic<int> state_{kIdle};
  Prepared* box_ = nullptr;
};

}  // namespace lode
