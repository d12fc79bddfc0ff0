// The base of the reference generators source.step, source.ramp, source.sine and
// source.zigzag: a Block whose output and runtime parameters (`lode set offset.x`, ...) are a
// SourceOutput, so that the Tunables API over its groups is written once.
//
// Threads: activate() on the loader thread; set_tunable() on the RT thread at a cycle
// boundary; tunables() off the RT thread after configure().
#pragma once

#include <cstddef>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/tunables.hpp"
#include "source_elements.hpp"

namespace lode::plugins::source {

class ElementSource : public Block, public Tunables {
 public:
  /// out = offset until the first step(); a source with state of its own to reset extends it.
  Status activate() override;

  /// The per-element runtime parameters of output_'s groups, in the order they were added.
  [[nodiscard]] std::vector<Tunable> tunables() const final { return output_.tunables(); }
  [[nodiscard]] double tunable_value(std::size_t index) const noexcept final { return output_.tunable_value(index); }
  /// Stores the value, to be used from the next sample on; a source that must keep its output
  /// continuous across a change overrides it (output_.locate(), its own bookkeeping, then
  /// output_.store()).
  bool set_tunable(std::size_t index, double value, const char*& why) noexcept override {
    return output_.set_tunable(index, value, why);
  }

 protected:
  SourceOutput output_;
};

}  // namespace lode::plugins::source
