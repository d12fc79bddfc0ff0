// A pipeline's cycle run back to back on the calling thread (no scheduler, no sleeping), each
// cycle timed with the monotonic clock: what `lode bench` prints and what `lode rtcheck
// --latency` subtracts from the period.
#pragma once

#include <cstdint>
#include <string>

#include "lode/pipeline.hpp"
#include "lode/sdk/histogram.hpp"

namespace lode::cli {

/// Activates the pipeline, runs `cycles` cycles on the simulated clock with each op timed
/// (Op::exec_time) and each whole cycle recorded in `whole`, then deactivates it. Returns ""
/// or why it stopped (activation refused, a fault at a named cycle and op).
std::string run_cycles_timed(Pipeline& pipeline, std::uint64_t cycles, Histogram& whole);

}  // namespace lode::cli
