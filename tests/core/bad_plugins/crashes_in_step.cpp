// A block with a bug that kills the process at a given cycle (issue 6: "a crash of the estimator
// path drives the outputs safe"): a write through a null pointer (SIGSEGV), or an exception
// escaping the noexcept step() (std::terminate -> SIGABRT), as a faulty estimator would.
#include <cstdint>
#include <stdexcept>
#include <string>

#include "lode/block.hpp"
#include "lode/plugin.hpp"

namespace {

// Out of line, so the throw is not seen inside step()'s noexcept at compile time.
[[gnu::noinline]] void throw_from_a_bug() { throw std::runtime_error("simulated bug in step()"); }

class CrashesInStep final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    at_cycle_ = static_cast<std::uint64_t>(ctx.params().integer("at_cycle", 100));
    abort_ = ctx.params().choice("how", {"segv", "throw"}, "segv") == "throw";
    return {};
  }
  lode::StepStatus step(const lode::Tick& tick) noexcept override {
    if (tick.cycle >= at_cycle_) {
      if (abort_) throw_from_a_bug();  // noexcept: std::terminate
      volatile int* nowhere = null_;
      *nowhere = 1;
    }
    return lode::StepStatus::ok;
  }

 private:
  std::uint64_t at_cycle_ = 100;
  bool abort_ = false;
  int* volatile null_ = nullptr;  // opaque to the optimiser: a real invalid write
};

constexpr lode::ParamDoc kParams[] = {
    {"at_cycle", "integer", "100", "the cycle whose step() crashes"},
    {"how", "text", "segv", "segv (write through a null pointer) or throw (exception out of noexcept step())"},
};
constexpr lode::PortDoc kPorts[] = {{"none", "-", "no ports"}};

}  // namespace

LODE_PLUGIN(CrashesInStep, "test.crashes_in_step", lode::PluginKind::block, "0.0.1",
            "Test plugin: step() crashes the process at a given cycle", kParams, kPorts)
