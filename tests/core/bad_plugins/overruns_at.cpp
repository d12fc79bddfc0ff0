// A block that makes the real-time loop overrun on purpose: its step() busy-waits a given time
// at given cycles, as an estimator with a rare slow path would. With `overrun_policy: skip` the
// scheduler then skips the periods lost, and the recording holds no rows for them.
#include <chrono>
#include <cstdint>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"

namespace {

class OverrunsAt final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    for (const double c : ctx.params().numbers("cycles")) cycles_.push_back(static_cast<std::uint64_t>(c));
    busy_ = std::chrono::microseconds(ctx.params().integer("busy_us", 4000));
    return {};
  }
  lode::StepStatus step(const lode::Tick& tick) noexcept override {
    for (const std::uint64_t c : cycles_) {
      if (c != tick.cycle) continue;
      const auto until = std::chrono::steady_clock::now() + busy_;
      while (std::chrono::steady_clock::now() < until) {
      }
    }
    return lode::StepStatus::ok;
  }

 private:
  std::vector<std::uint64_t> cycles_;
  std::chrono::microseconds busy_{4000};
};

constexpr lode::ParamDoc kParams[] = {
    {"cycles", "list of integers", nullptr, "the cycles whose step() busy-waits"},
    {"busy_us", "integer", "4000", "how long each of them busy-waits"},
};

}  // namespace

LODE_PLUGIN(OverrunsAt, "test.overruns_at", lode::PluginKind::source, "0.0.1",
            "Test plugin: step() busy-waits at given cycles (forces overruns on the real clock)", kParams,
            lode::kNoPorts)
