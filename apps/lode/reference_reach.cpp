#include "reference_reach.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "lode/sdk/text.hpp"

namespace lode::cli {

namespace {

/// Where each element of the reference is furthest below and above zero, and when.
struct Reach {
  std::vector<double> low, high;
  std::vector<std::int64_t> low_ns, high_ns;
};

}  // namespace

std::vector<std::string> reference_outside_envelope(Pipeline& pipeline) {
  std::vector<std::string> warnings;
  const auto& reference = pipeline.monitor().reference;
  if (!reference || reference->data == nullptr || reference->size() == 0) return warnings;
  if (pipeline.plugin_of(reference->block).rfind("source.", 0) != 0) return warnings;
  Block* block = pipeline.block(reference->block);
  if (block == nullptr) return warnings;
  const auto bounds = pipeline.envelope_bounds();
  if (bounds.empty()) return warnings;

  // A run without a set duration is followed for an hour: long enough for any trajectory a
  // test script gives, short enough to take a fraction of a second.
  const double duration_s = std::min(pipeline.default_duration_s().value_or(3600.0), 3600.0);
  const std::int64_t period_ns = pipeline.period_ns();
  const auto cycles = static_cast<std::uint64_t>(std::ceil(duration_s * 1e9 / static_cast<double>(period_ns)));
  if (!block->activate()) return warnings;
  const std::size_t n = reference->size();
  Reach reach{std::vector<double>(n, std::numeric_limits<double>::infinity()),
              std::vector<double>(n, -std::numeric_limits<double>::infinity()), std::vector<std::int64_t>(n, 0),
              std::vector<std::int64_t>(n, 0)};
  Tick tick;
  tick.dt_s = static_cast<double>(period_ns) * 1e-9;
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tick.cycle = k;
    tick.time_ns = static_cast<std::int64_t>(k) * period_ns;
    if (block->step(tick) != StepStatus::ok) break;
    for (std::size_t i = 0; i < n; ++i) {
      const double v = reference->data[i];
      if (v < reach.low[i]) reach.low[i] = v, reach.low_ns[i] = tick.time_ns;
      if (v > reach.high[i]) reach.high[i] = v, reach.high_ns[i] = tick.time_ns;
    }
  }
  block->deactivate();

  const Elements& elements = *reference->elements;
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& bound : bounds) {
      if (bound.signal.elements == nullptr) continue;
      const Elements& theirs = *bound.signal.elements;
      for (std::size_t j = 0; j < theirs.size() && j < bound.min.size() && j < bound.max.size(); ++j) {
        if (theirs[j].name != elements[i].name || theirs[j].unit != elements[i].unit) continue;
        const bool below = reach.low[i] < bound.min[j];
        const bool above = reach.high[i] > bound.max[j];
        if (!below && !above) continue;
        const double value = above ? reach.high[i] : reach.low[i];
        const double at_s = static_cast<double>(above ? reach.high_ns[i] : reach.low_ns[i]) * 1e-9;
        const std::string& unit = elements[i].unit;
        warnings.push_back(reference->name() + "." + elements[i].name + " reaches " + number_text(value) + " " + unit +
                           " at t = " + number_text(at_s) + " s; the envelope keeps " + bound.signal.name() + "." +
                           theirs[j].name + " within [" + number_text(bound.min[j]) + ", " + number_text(bound.max[j]) +
                           "] " + unit + ": the run will fault when the stage follows it");
      }
    }
  }
  return warnings;
}

}  // namespace lode::cli
