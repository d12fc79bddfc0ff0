// Host one block outside a pipeline, through the same port API the scheduler uses: plugin
// unit tests (as lode::testing::BlockHarness) and tools that need one block on its own, such
// as a board emulator playing the plant behind a register interface.
//
//   lode::BlockHost h("estimator.kalman", R"(
//       motion: constant_acceleration
//       q: [100, 100, 1e5])", 800.0);
//   h.feed("input", {{"x","m"},{"y","m"},{"theta_z","rad"}});   // a test source
//   ASSERT_TRUE(h.configure()) << h.diagnostics();
//   ASSERT_TRUE(h.activate());
//   h.input("input")[0] = 1e-4;  h.step();
//   double x = h.output("pose")[0];
//
// The block and any models it asks for are loaded from the plugin search path (the build
// tree's plugin folder first), exactly as `lode run` loads them. `models_yaml` is the text
// of a pipeline's `models:` map.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/tunables.hpp"

namespace lode {

class BlockHost {
 public:
  BlockHost(std::string plugin, std::string params_yaml, double rate_hz,
               std::string models_yaml = {});
  ~BlockHost();

  /// Declare a test source for input `name` with these elements. Call before configure().
  void feed(const std::string& name, Elements elements);

  /// configure(); on failure diagnostics() tells why. Binds ports on success.
  Status configure();
  Status activate();
  StepStatus step();   ///< advances the tick
  /// The tick jumps to `cycle` (as a real-time loop's after it skipped periods), then step().
  StepStatus step_at(std::uint64_t cycle);
  StepStatus write();  ///< io blocks: write phase of the current tick
  void deactivate();

  std::span<double> input(const std::string& name);
  std::span<const double> output(const std::string& name) const;
  [[nodiscard]] const Elements& output_elements(const std::string& name) const;
  [[nodiscard]] Json describe() const;
  [[nodiscard]] std::string diagnostics() const;
  [[nodiscard]] const Tick& tick() const;
  Block& block();
  /// The block's optional interfaces; each throws std::logic_error when the block has none
  /// (a test that asks for one expects the plugin to implement it).
  Tunables& tunables();
  EstimatorState& estimator();
  Board& board();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lode
