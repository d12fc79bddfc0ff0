// What `lode plot` draws, read from recordings: for each axis of the pipeline's state the
// reference, the truth and every estimate (from the primary recording and from replays of
// it), on one time grid; and the min/max pyramid that lets a browser draw millions of samples.
//
// Which recorded series is the reference, the truth or an estimate is what the recording's
// pipeline says (its `config` attribute, loaded as `lode run` loads it: monitor.reference,
// monitor.truth, monitor.estimate and each shadow's output, monitor.record outputs shaped
// like the truth). A recording without a loadable configuration (`lode record` of DDS
// topics) falls back to the series' names: see find_roles_by_name().
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/record/hdf5_recorder.hpp"

namespace lode::plot {

/// One recording and the pipeline that wrote it (null when its configuration is absent or
/// no longer loads; `notes` says why).
struct LoadedRecording {
  std::string path;
  std::string label;  ///< the file name, to tell replays apart
  record::Recording recording;
  std::unique_ptr<Pipeline> pipeline;
  std::vector<std::string> notes;
  record::SeriesSelection plotted = record::SeriesSelection::all();  ///< what read_plotted() reads
  [[nodiscard]] std::string text(const std::string& key) const;
  [[nodiscard]] std::optional<double> number(const std::string& key) const;
  [[nodiscard]] const record::SeriesData* series(const std::string& name) const;
};

/// Reads `path`'s attributes and loads its configuration with `registry` (which must outlive
/// the result), and chooses the series a report needs: with a configuration, those its
/// monitor: section and estimators name (the rest of a recording, such as a board's raw
/// inputs, is never plotted); without one, all of them (roles are then found by name).
/// No series is read yet: read_plotted() does.
Expected<LoadedRecording> open_recording(const std::string& path, PluginRegistry& registry);

/// Whether `replay` (read) replays `recording` (read): a replay's boards play back the
/// recording's raw series bit for bit, so every raw series both hold must agree on the rows
/// both have (a replay that faulted early has fewer). An error names the first difference;
/// a replay with no raw series in common is let through with a note.
Status check_replay_of(const LoadedRecording& recording, const LoadedRecording& replay, std::vector<std::string>& notes);

/// What read_plotted() will hold of `loaded`'s recording (record::read_cost).
Expected<std::uint64_t> plotted_bytes(const LoadedRecording& loaded);

/// Reads the series open_recording() chose.
Status read_plotted(LoadedRecording& loaded);

/// open_recording() and read_plotted().
Expected<LoadedRecording> load_recording(const std::string& path, PluginRegistry& registry);

/// The series that play each part, by name ("block.port"); empty when absent.
struct SeriesRoles {
  std::string reference, truth;
  struct Estimate {
    std::string series;
    std::string role;  ///< "monitor.estimate", "shadow of kf", "monitor.record", "by name"
  };
  std::vector<Estimate> estimates;
  double hold_start_s = 0.0, hold_end_s = 0.0;  ///< the monitor's hold window (0, 0: none)
  double settle_band = 0.02;
};

/// From the loaded pipeline when there is one, else by name.
SeriesRoles find_roles(const LoadedRecording& loaded);

/// Without a configuration: a series whose port is `truth` is the truth, one whose block or
/// port is `ref`/`reference` the reference, and every other non-raw series with the truth's
/// (else the reference's) element names and units is an estimate.
SeriesRoles find_roles_by_name(const record::Recording& recording);

/// The sample times of the primary recording's rows. Uniform when every step is the same
/// number of nanoseconds (the cycle grid of `lode run`), so the page needs only t0 and dt.
struct TimeGrid {
  std::vector<double> time_s;
  bool uniform = false;
  double t0 = 0.0, dt = 0.0;
  [[nodiscard]] std::size_t size() const { return time_s.size(); }
};
TimeGrid time_grid(const record::SeriesData& series);

/// One plotted curve: an element of a series, on the primary recording's grid.
struct Trace {
  std::string label;   ///< "kf.pose", or "kf.pose @ run.replay-cv.h5" for a second file
  std::string role;    ///< "reference" | "truth" | "estimate" | "error"
  std::string detail;  ///< how it was found: "monitor.estimate", "shadow of kf", ...
  std::vector<double> values;  ///< one per grid sample; NaN where its file has no row
  /// For an error: the labels of the estimate and the truth it is the difference of, on the
  /// same axis. The page recomputes its samples from theirs rather than store them twice.
  std::string minuend, subtrahend;
};

struct AxisTraces {
  std::string name, unit;
  std::vector<Trace> traces;  ///< reference, truth, then the estimates
  [[nodiscard]] const Trace* find_role(const std::string& role) const;
};

struct PlotSignals {
  TimeGrid grid;
  std::vector<AxisTraces> axes;
  /// What was left out and why ("kf.pose @ run.replay.h5 is bit-identical to kf.pose: drawn once").
  std::vector<std::string> notes;
};

/// Every axis of the truth (else the reference, else the first estimate) with the curves of
/// every recording in `files` (the first is the primary: its rows are the grid). A file whose
/// cycles are not the primary's is matched row by cycle; rows it lacks are NaN. A later file's
/// estimate equal bit for bit on every axis to the same series of an earlier file (a replay
/// through the recorded configuration) is drawn once, with a note.
PlotSignals collect_axes(const std::vector<const LoadedRecording*>& files, const std::vector<SeriesRoles>& roles);

/// Estimate minus truth for every estimate of every axis (role "error").
std::vector<AxisTraces> estimation_errors(const std::vector<AxisTraces>& axes);

// ---- display decimation -------------------------------------------------------------------

/// The min and max of every bucket of `bucket` consecutive samples (the last may be shorter),
/// NaN ignored (a bucket of NaN only is NaN). Drawing a vertical stroke from min to max per
/// bucket shows every excursion of the signal however many samples share a pixel.
struct MinMaxLevel {
  std::size_t bucket = 0;
  std::vector<double> min, max;
};

/// Levels of buckets first_bucket, first_bucket * factor, ... while a level still has more
/// than `coarsest` buckets; each level is built from the one below (so one pass over the data).
/// The samples themselves are the finest level and are not repeated here.
std::vector<MinMaxLevel> min_max_pyramid(const std::vector<double>& values, std::size_t first_bucket = 16,
                                         std::size_t factor = 4, std::size_t coarsest = 2048);

}  // namespace lode::plot
