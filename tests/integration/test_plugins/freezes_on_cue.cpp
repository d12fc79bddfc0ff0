// A filter that freezes the real-time loop when told to, for the service watchdog's tests
// (tests/integration/service_notify_test.py, and the systemd end-to-end test in a guest). It
// passes its input through until its tunable `freeze` is set to 1 (`lode set BLOCK.freeze 1`
// on the local socket); from the next step() on it never returns (a sleep loop), as a plugin
// caught in an endless iteration or a blocking call would. The rest of the process stays
// alive: only the loop's missing progress can tell systemd's watchdog that something is wrong.
// Test-only: never installed.
#include <time.h>

#include <atomic>
#include <cstddef>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/tunables.hpp"

namespace {

class FreezesOnCue final : public lode::Block, public lode::Tunables {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    lode::Params& params = ctx.params();
    freeze_.store(params.integer("freeze", 0) != 0);
    ctx.declare_input(in_, "in", {}, true);
    const lode::Elements* source = ctx.input_source("in");
    if (source == nullptr || source->empty()) {
      params.fail("inputs", "`in` must come from a configured output");
      return lode::Status::error("invalid parameters");
    }
    ctx.declare_output(out_, "out", *source);
    size_ = source->size();
    return params.ok() ? lode::Status::ok() : lode::Status::error("invalid parameters");
  }

  lode::StepStatus step(const lode::Tick&) noexcept override {
    // Frozen: stay here for ever, sleeping so the stuck RT thread does not starve the host.
    while (freeze_.load(std::memory_order_relaxed)) {
      const timespec ms{0, 1'000'000};
      nanosleep(&ms, nullptr);
    }
    for (std::size_t i = 0; i < size_; ++i) out_[i] = in_[i];
    return lode::StepStatus::ok;
  }

  [[nodiscard]] std::vector<lode::Tunable> tunables() const override {
    return {{"freeze", "bool", 0, 1, true, "1: the next step() never returns"}};
  }
  [[nodiscard]] double tunable_value(std::size_t) const noexcept override { return freeze_.load() ? 1.0 : 0.0; }
  bool set_tunable(std::size_t, double value, const char*&) noexcept override {
    freeze_.store(value != 0.0);
    return true;
  }

 private:
  std::atomic<bool> freeze_{false};
  std::size_t size_ = 0;
  lode::InputPort in_;
  lode::OutputPort out_;
};

constexpr lode::ParamDoc kParams[] = {
    {"freeze", "integer", "0", "1: step() never returns (also a runtime parameter: lode set BLOCK.freeze 1)"},
};
constexpr lode::PortSpec kPorts[] = {
    {"in", lode::PortDirection::in, "any signal"},
    {"out", lode::PortDirection::out, "the input, passed through (until frozen)"},
};

}  // namespace

LODE_PLUGIN(FreezesOnCue, "test.freezes_on_cue", lode::PluginKind::filter, "0.0.1",
            "Test plugin: a pass-through filter whose step() never returns once its tunable freeze is 1", kParams,
            kPorts)
