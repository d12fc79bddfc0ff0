// Whether the commanded trajectory stays where the envelope lets the stage go: `lode check`
// steps the pipeline's reference generator alone over the run and compares where it goes
// with the envelope's bounds on the signals that follow it (the truth, the estimate).
#pragma once

#include <string>
#include <vector>

#include "lode/pipeline.hpp"

namespace lode::cli {

/// One warning per element of monitor.reference that goes outside the envelope bound of a
/// signal with the same element name and unit ("ref.out.x reaches 0.1 m at t = 1 s; the
/// envelope keeps stage.truth.x within [-0.08, 0.08] m: the run will fault when the stage
/// follows it"). Empty when there is no reference, it is not made by a source.* block (only
/// a generator with no inputs can be stepped on its own), or it stays inside. Steps the
/// reference block over the run's duration (default_duration_s(), at most an hour of cycles)
/// after activating it; the pipeline must not be running.
std::vector<std::string> reference_outside_envelope(Pipeline& pipeline);

}  // namespace lode::cli
