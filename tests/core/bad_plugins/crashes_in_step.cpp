// A block with a bug that kills the process at a given cycle ("a crash of the estimator
// path drives the outputs safe"): a write through a null pointer (SIGSEGV), an exception
// escaping the noexcept step() (std::terminate -> SIGABRT), or unbounded recursion (SIGSEGV on
// the RT thread's stack guard: the handler needs its alternate stack), as a faulty estimator would.
#include <cstdint>
#include <stdexcept>
#include <string>

#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"

namespace {

// Out of line, so the throw is not seen inside step()'s noexcept at compile time.
[[gnu::noinline]] void throw_from_a_bug() { throw std::runtime_error("simulated bug in step()"); }

// Recursion the compiler cannot turn into a loop: each frame keeps a live volatile buffer.
[[gnu::noinline]] int recurse_forever(int depth) {
  volatile char frame[256];
  frame[depth % 256] = static_cast<char>(depth);
  return recurse_forever(depth + 1) + frame[(depth + 1) % 256];
}

class CrashesInStep final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    at_cycle_ = static_cast<std::uint64_t>(ctx.params().integer("at_cycle", 100));
    how_ = ctx.params().choice("how", {"segv", "throw", "overflow"}, "segv");
    return {};
  }
  lode::StepStatus step(const lode::Tick& tick) noexcept override {
    if (tick.cycle >= at_cycle_) {
      if (how_ == "throw") throw_from_a_bug();  // noexcept: std::terminate
      if (how_ == "overflow") sink_ = recurse_forever(0);
      volatile int* nowhere = null_;
      *nowhere = 1;
    }
    return lode::StepStatus::ok;
  }

 private:
  std::uint64_t at_cycle_ = 100;
  std::string how_;
  volatile int sink_ = 0;
  int* volatile null_ = nullptr;  // opaque to the optimiser: a real invalid write
};

constexpr lode::ParamDoc kParams[] = {
    {"at_cycle", "integer", "100", "the cycle whose step() crashes"},
    {"how", "text", "segv",
     "segv (write through a null pointer), throw (exception out of noexcept step()) or overflow (stack)"},
};
constexpr lode::PortSpec kPorts[] = {{"none", "-", "no ports"}};

}  // namespace

LODE_PLUGIN(CrashesInStep, "test.crashes_in_step", lode::PluginKind::block, "0.0.1",
            "Test plugin: step() crashes the process at a given cycle", kParams, kPorts)
