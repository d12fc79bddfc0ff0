// A loaded pipeline with its hot swap, the test thread playing the RT thread: every cycle
// runs the before_cycle hooks, run_cycle and the after_cycle hooks, as the scheduler does,
// so a test of swaps, shadows or the health monitor is reproducible cycle by cycle.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/hot_swap.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/sdk/testing/allocation_counter.hpp"

namespace lode::test {

struct SwapRig {
  /// Loads `yaml` (labelled `label` in diagnostics) with the default plugin search path and
  /// `extra_search`, activates it and marks the swapper running.
  explicit SwapRig(const std::string& yaml, const std::string& label, std::vector<std::string> extra_search = {}) {
    auto path = PluginRegistry::default_search_path();
    path.insert(path.end(), extra_search.begin(), extra_search.end());
    registry = std::make_unique<PluginRegistry>(path);
    pipeline = Pipeline::load_text(yaml, label, *registry, diagnostics);
    if (!pipeline) return;
    swapper = std::make_unique<HotSwap>(*pipeline, events);
    activated = static_cast<bool>(pipeline->activate());
    swapper->set_running(true);
  }

  /// One cycle. `at_cycle_end` runs after run_cycle, before the after_cycle hooks (where an
  /// exchange happens). The heap allocations from the first hook to the last are counted into
  /// last_cycle_allocations; what the test reads afterwards is not.
  Pipeline::CycleResult step(const std::function<void()>& at_cycle_end = {}) {
    Tick t;
    t.cycle = cycle;
    t.time_ns = static_cast<std::int64_t>(cycle) * pipeline->period_ns();
    t.dt_s = 1.0 / pipeline->rate_hz();
    const auto before = testing::allocation_count();
    swapper->before_cycle(t);
    const auto r = pipeline->run_cycle(t, true);
    if (at_cycle_end) at_cycle_end();
    swapper->after_cycle(t);
    last_cycle_allocations = testing::allocation_count() - before;
    ++cycle;
    return r;
  }

  /// The values of "block.port" now (empty if there is no such output).
  [[nodiscard]] std::vector<double> value(const std::string& signal) const {
    auto s = pipeline->signal(signal);
    return s ? std::vector<double>(s->data, s->data + s->size()) : std::vector<double>{};
  }

  std::unique_ptr<PluginRegistry> registry;
  Diagnostics diagnostics;
  EventLog events;
  std::unique_ptr<Pipeline> pipeline;
  std::unique_ptr<HotSwap> swapper;
  bool activated = false;
  std::uint64_t cycle = 0;
  std::size_t last_cycle_allocations = 0;
};

}  // namespace lode::test
