// A pipeline's cycle run back to back on the calling thread (no scheduler, no sleeping), each
// cycle timed with the monotonic clock: what `lode bench` prints and what `lode rtcheck
// --latency` subtracts from the period. The cycle includes the output digest, which `lode run`
// computes on the RT thread after every cycle.
#pragma once

#include <cstdint>
#include <string>

#include "lode/pipeline.hpp"
#include "lode/sdk/histogram.hpp"

namespace lode::cli {

/// Activates the pipeline, runs `cycles` cycles on the simulated clock with each op timed
/// (Op::exec_time), the output digest after each (timed into `digest` when given), and each
/// whole cycle, digest included, recorded in `whole`; then deactivates it. Returns "" or why
/// it stopped (activation refused, a fault at a named cycle and op).
std::string run_cycles_timed(Pipeline& pipeline, std::uint64_t cycles, Histogram& whole, Histogram* digest = nullptr);

}  // namespace lode::cli
