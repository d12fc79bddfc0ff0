#include "cycle_allocations.hpp"

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <memory>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/scheduler.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"
#include "lode/testing/private_domain.hpp"
#include "run_services.hpp"

namespace lode::testing {

namespace {

/// The cycle thread's allocation count at the start of the first cycle (the first hook) and
/// at the end of every cycle (the last hook). Reading a thread-local counter allocates nothing.
class AllocationProbe final : public CycleHook {
 public:
  void before_cycle(const Tick& tick) noexcept override {
    if (opening_ && !started_) {
      started_ = true;
      first_ = thread_allocation_count();
      first_cycle_ = tick.cycle;
    }
  }
  void after_cycle(const Tick& tick) noexcept override {
    if (opening_) return;
    last_.store(thread_allocation_count(), std::memory_order_relaxed);
    last_cycle_.store(tick.cycle, std::memory_order_release);
    cycles_.fetch_add(1, std::memory_order_release);
  }
  static AllocationProbe opening() { return AllocationProbe(true); }
  static AllocationProbe closing() { return AllocationProbe(false); }

  [[nodiscard]] bool started() const { return started_; }
  [[nodiscard]] std::size_t first() const { return first_; }
  [[nodiscard]] std::size_t last() const { return last_.load(std::memory_order_relaxed); }
  // Read by the idle callback, which under the real clock runs on the main thread.
  [[nodiscard]] std::uint64_t cycles() const { return cycles_.load(std::memory_order_acquire); }

 private:
  explicit AllocationProbe(bool opening) : opening_(opening) {}
  bool opening_;
  std::atomic<bool> started_{false};
  std::size_t first_ = 0;
  std::atomic<std::size_t> last_{0};
  std::uint64_t first_cycle_ = 0;
  std::atomic<std::uint64_t> cycles_{0};
  std::atomic<std::uint64_t> last_cycle_{0};
};

struct TemporaryFolder {
  std::filesystem::path path;
  TemporaryFolder() {
    std::string pattern = (std::filesystem::temp_directory_path() / "lode_cycle_alloc_XXXXXX").string();
    if (::mkdtemp(pattern.data()) != nullptr) path = pattern;
  }
  ~TemporaryFolder() {
    std::error_code ignored;
    if (!path.empty()) std::filesystem::remove_all(path, ignored);
  }
};

}  // namespace

CycleAllocationRun measure_cycle_allocations(const std::string& yaml, const std::string& file,
                                             const CycleAllocationOptions& options) {
  CycleAllocationRun out;
  PluginRegistry registry;
  Diagnostics diag;
  auto pipeline = Pipeline::load_text(yaml, file, registry, diag);
  if (!pipeline) {
    out.error = diag.format();
    return out;
  }
  TemporaryFolder folder;
  SimulatedClock simulated;
  RealClock real;
  Clock& clock = options.real_clock ? static_cast<Clock&>(real) : static_cast<Clock&>(simulated);
  EventLog events;
  Scheduler scheduler(*pipeline, clock, events);
  AllocationProbe opening = AllocationProbe::opening(), closing = AllocationProbe::closing();
  scheduler.add_hook(&opening);  // first: before the services' hooks

  cli::RunServiceOptions service_options;
  service_options.telemetry = options.telemetry;
  service_options.domain = private_dds_domain();
  service_options.simulated = !options.real_clock;
  service_options.local_control = false;  // its server thread is not on the cycle path
  if (options.record) service_options.record_path = (folder.path / "cycles.h5").string();
  auto services = cli::RunServices::start(*pipeline, scheduler, events, service_options);
  if (!services) {
    out.error = services.error();
    return out;
  }
  scheduler.add_hook(&closing);  // last: after the taps and the digest

  // Under the simulated clock the idle callback runs on the cycle thread between cycles:
  // whatever it allocates is the non-real-time side's and is subtracted, but only for calls
  // that a later cycle closed (the last calls come after the window). No allocation here.
  std::size_t idle_inside = 0, idle_pending = 0;
  std::uint64_t cycles_at_pending = 0;
  const auto on_idle = [&] {
    const std::size_t before = thread_allocation_count();
    (*services)->on_idle();
    const std::size_t made = thread_allocation_count() - before;
    if (!opening.started()) return;
    if (closing.cycles() != cycles_at_pending) {
      idle_inside += idle_pending;
      idle_pending = 0;
      cycles_at_pending = closing.cycles();
    }
    idle_pending += made;
  };
  auto result = cli::execute_run(*pipeline, scheduler, events, **services, options.cycles, "allocation sweep",
                                 on_idle);
  if (!result) {
    out.error = result.error();
    return out;
  }
  if (closing.cycles() != cycles_at_pending) idle_inside += idle_pending;
  out.configured = true;
  out.faulted = result->faulted;
  out.fault = result->fault;
  out.cycles = closing.cycles();
  const std::size_t inside = closing.last() - opening.first();
  out.allocations = options.real_clock ? inside : inside - idle_inside;
  out.events = events.snapshot();
  const Json summary = (*services)->summary();
  if (const Json* telemetry = summary.find("telemetry"))
    if (const Json* published = telemetry->find("published"))
      out.telemetry_published = static_cast<std::uint64_t>(published->as_number());
  if (const Json* recordings = summary.find("recordings"); recordings && !recordings->elements().empty())
    if (const Json* cycles = recordings->elements()[0].find("cycles"))
      out.recorded_cycles = static_cast<std::uint64_t>(cycles->as_number());
  return out;
}

}  // namespace lode::testing
