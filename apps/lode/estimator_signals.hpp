// Which outputs of a pipeline are estimates of its state, shared by the commands that compare
// estimators (`lode replay`, `lode plot`) so that both name the same ones.
#pragma once

#include <string>
#include <vector>

#include "lode/pipeline.hpp"

namespace lode::cli {

struct EstimatorSignal {
  SignalRef signal;
  std::string role;  ///< "monitor.estimate", "shadow of <primary>"
};

/// monitor.estimate, then each shadow's output on the same port, each once. A shadow without
/// that port is named in `notes` ("shadow S has no output 'P' to compare").
std::vector<EstimatorSignal> estimator_signals(const Pipeline& pipeline, std::vector<std::string>& notes);

}  // namespace lode::cli
