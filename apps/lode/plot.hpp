// The HTML report of `lode plot`, for the commands that write one (lode plot, lode replay
// --report R.html).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace lode::cli {

/// Writes the self-contained HTML report of `recordings` to `output`: the first is a run's
/// recording, the others replays of it whose estimates are shown beside its own. Problems go
/// to stderr; returns the `lode` exit code. `figures` (optional) receives the figure ids.
int write_plot_report(const std::vector<std::string>& recordings, const std::filesystem::path& output, bool quiet,
                      std::vector<std::string>* figures = nullptr);

}  // namespace lode::cli
