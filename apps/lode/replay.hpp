// `lode replay`: run the raw inputs of a recording through the recorded configuration (a
// bit-exactness check) and through other estimator sets, with a comparison report.
//
//   lode replay RECORDING [--config OTHER.yaml ...] [--output OUT.h5] [--report REPORT.md|.json]
//               [--reference block.port] [--estimate block.port ...] [--quiet]
//
// Each configuration is turned into a replay by rewriting every block whose plugin is of
// kind io into io.replay playing that block's recorded outputs (the other lines of the file
// are untouched, so diagnostics keep the user's line numbers), then run on the simulated
// clock for exactly the recorded number of cycles.
#pragma once

#include <string>
#include <vector>

#include "cli.hpp"
#include "lode/plugin_loader.hpp"

namespace lode::cli {

/// The configuration text with every io block replaced by
/// `{plugin: io.replay, recording: <recording>, block: <name>, inputs: <its inputs>}`.
/// Line numbers of everything else are kept (the replaced block's lines become one line
/// plus blank lines). `replaced` receives the names of the rewritten blocks; `note` is
/// set when the file could only be rewritten as a whole (flow-style `blocks:`), in which
/// case line numbers refer to the rewritten text. Unparsable text is returned unchanged
/// (loading it reports the syntax error at its place).
std::string rewrite_for_replay(const std::string& yaml, const std::string& recording, PluginRegistry& registry,
                               std::vector<std::string>& replaced, std::string& note);

/// Wilson-Hilferty approximation of the chi-square quantile with k degrees of freedom at
/// probability p (Wilson & Hilferty 1931; accurate to ~1 % for k >= 1 at 2.5 / 97.5 %).
double chi_square_quantile(double p, double k);

/// `lode replay ...` (argv[1] == "replay"). Exit codes: 0 ok, 1 replay fault or bit
/// mismatch, 2 usage or configuration error.
int cmd_replay(const Args& args);

}  // namespace lode::cli
