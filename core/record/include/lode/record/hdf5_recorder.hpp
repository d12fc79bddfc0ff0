// Recordings as HDF5 files that open in Python (h5py, pandas) and MATLAB (h5read, h5info)
// without lodestone: every signal is a group of plain 1-D datasets whose names and SI units
// are attributes. The file layout is in core/record/README.md.
//
// Threads: a Recorder belongs to one non-RT writer thread (`lode record`, the telemetry
// drainer of `lode run`); it is not thread-safe and never runs on the RT thread, which only
// pushes into a SampleRing. Debian's libhdf5 is the thread-safe build, so two Recorders on two
// threads are correct, but they serialise on HDF5's global lock.
//
// Memory and crash safety: append() buffers rows in memory and writes one chunk at a time
// (chunk = min(4096 rows, 1 s of samples), at least 64 rows), so memory stays bounded even if
// flush() is never called. flush() writes every buffered row and event, refreshes the
// counters and calls H5Fflush: if the process dies after flush() returned, the file holds
// every sample appended before it (the OS still has to write its page cache: a power cut
// is not covered, there is no fsync).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "lode/sdk/status.hpp"

namespace lode::record {

/// What one recorded series is. Written as attributes of /signals/<name>.
struct SeriesInfo {
  std::string name;                ///< "glsdc.pose": group name under /signals (no '/', not "." or "")
  std::string topic;               ///< "lode/kawato_planar/glsdc/pose", or "" for local recordings
  std::string kind = "signal";     ///< "signal" | "state" | "raw" (raw ADC inputs, used by replay)
  std::vector<std::string> names;  ///< one per value, unique within the series
  std::vector<std::string> units;  ///< SI, one per value ("m", "rad", "V", "" for dimensionless)
  double rate_hz = 0;              ///< sample rate of this series (0 = unknown)
  double pipeline_rate_hz = 0;     ///< base rate of the pipeline that produced it (0 = unknown)
  std::uint32_t decimation = 1;    ///< pipeline cycles between two samples of this series
};

/// The dataset name that stores value `index` of a series whose element names are `names`:
/// the element name itself unless it collides with cycle/stamp_ns/captured_ns/time_s or is
/// not a valid HDF5 link name ("", ".", or containing '/'); then it is "value_" + the name
/// with every '/' replaced by '_' ("value_3" for an empty name at index 3). The original name
/// is kept in the dataset's `name` attribute and in the group's `names` attribute.
[[nodiscard]] std::string dataset_name_for(const std::string& element_name, std::size_t index);

class Recorder {
 public:
  /// Creates `path`, replacing a file already there (a plain file with one name is removed
  /// first, any other is truncated). `source` says which program writes it: "lode record", "lode run".
  static Expected<std::unique_ptr<Recorder>> create(const std::string& path, const std::string& source);
  ~Recorder();  ///< closes (flushes) if still open; an error then is lost: call close() to see it

  // Identity-bearing (owns the open file): neither copyable nor movable.
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  Recorder(Recorder&&) = delete;
  Recorder& operator=(Recorder&&) = delete;

  /// Root attributes: pipeline, config (resolved YAML text), host, ... A key set twice keeps
  /// the last value. Text is stored as a variable-length UTF-8 string, so its size is unbounded.
  void set_attribute(const std::string& key, const std::string& value);
  void set_attribute(const std::string& key, double value);

  /// Adds /signals/<info.name>; may be called at any time (a topic that appears later).
  /// Returns the series handle for append(). Fails (naming the field) on an invalid or
  /// duplicate name, names/units of different lengths, no values, duplicate element names,
  /// an unknown kind, decimation 0 or a negative rate.
  Expected<int> add_series(const SeriesInfo& info);

  /// One sample: `values` points to info.names.size() doubles (stored bit for bit, NaN
  /// payloads included). `cycle` is the pipeline cycle, `stamp_ns` the scheduled time since the
  /// run started, `captured_ns` CLOCK_MONOTONIC of the RT host at capture. A cycle that skips
  /// more than `decimation` counts the missing samples in gaps(); a cycle that does not
  /// increase counts in out_of_order(). Errors (unknown series, write failure, after close)
  /// cannot be returned here: they are kept and returned by the next flush()/close().
  void append(int series, std::uint64_t cycle, std::int64_t stamp_ns, std::int64_t captured_ns, const double* values);

  /// The number of rows every series will get, when it is known before the first
  /// add_series() (a replay runs a known number of cycles): the series added after it are
  /// created at that length, in chunks of up to 2048 rows written without HDF5's chunk
  /// cache, so a chunk costs one H5Dwrite per column and no H5Dset_extent. More rows still
  /// extend the datasets; fewer are cut off at close(). Memory: up to one chunk of rows per
  /// series is held before it is written.
  void expect_rows(std::uint64_t rows);

  /// `count` samples at once: row r is cycle[r], stamp_ns[r] and the series' values at
  /// values + r * stride (captured_ns 0). Same bookkeeping as append() row by row, without a
  /// call per row.
  void append_rows(int series, std::size_t count, const std::uint64_t* cycle, const std::int64_t* stamp_ns,
                   const double* values, std::size_t stride);

  /// One row of /events (start, stop, fault, parameter change, ...).
  void add_event(std::uint64_t cycle, std::int64_t stamp_ns, const std::string& kind, const std::string& text);

  /// Writes buffered rows and events, the counters, and calls H5Fflush: after flush() a crash
  /// loses nothing appended before it. Returns the first error since the last flush, if any.
  Status flush();
  /// flush(), writes the counters (samples, gaps) as attributes and closes the file.
  /// Idempotent; append() after close() is an error reported by nothing (the file is closed).
  Status close();

  [[nodiscard]] std::uint64_t samples(int series) const;
  /// Samples missing between consecutive cycles (vs the decimation): a lost sample is visible.
  /// After account(): the count given there.
  [[nodiscard]] std::uint64_t gaps(int series) const;
  /// What the caller knows better than the cycle numbers: of the samples the cycles say are
  /// absent, `missing` were lost and `skipped` were never due (periods the real-time loop
  /// skipped after an overrun publish nothing). Replaces gaps(); both are written as the
  /// series' `gaps` and `skipped` attributes at the next flush() or close().
  void account(int series, std::uint64_t missing, std::uint64_t skipped);
  /// Samples whose cycle was not greater than the previous one (duplicates, reordering).
  [[nodiscard]] std::uint64_t out_of_order(int series) const;
  [[nodiscard]] const std::string& path() const;

 private:
  struct Impl;
  explicit Recorder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// ---- Reading back (replay and tests use it) ----------------------------------------------

struct SeriesData {
  SeriesInfo info;
  std::vector<std::uint64_t> cycle;
  std::vector<std::int64_t> stamp_ns, captured_ns;
  std::vector<double> values;      ///< row-major N x width (width = info.names.size())
  std::uint64_t gaps = 0;          ///< the `gaps` attribute (as of the last flush/close)
  std::uint64_t out_of_order = 0;  ///< the `out_of_order` attribute
  [[nodiscard]] std::size_t rows() const { return cycle.size(); }
  [[nodiscard]] std::size_t width() const { return info.names.size(); }
};

struct Recording {
  std::map<std::string, std::string> text_attributes;  ///< root string attributes (format, source, created_utc, ...)
  std::map<std::string, double> number_attributes;     ///< root numeric attributes (format_version, ...)
  std::vector<SeriesData> series;                      ///< in the order they were added
  /// The series in the file that a SeriesSelection left out (their names, in file order).
  std::vector<std::string> series_not_read;
  struct Ev {
    std::uint64_t cycle;
    std::int64_t stamp_ns;
    std::string kind, text;
  };
  std::vector<Ev> events;
  /// Things a reader should know: e.g. a file from a crashed writer whose columns have
  /// different lengths is cut to the rows present in every column, and that is said here.
  std::vector<std::string> warnings;
};

/// Which series of a recording to read: `wanted(name, kind)` (kind: "signal", "state", "raw").
/// `key` names the selection for read_recording_shared(): equal keys, equal selections.
struct SeriesSelection {
  std::string key;
  std::function<bool(const std::string& name, const std::string& kind)> wanted;

  /// Every series (what read_recording(path) reads).
  static SeriesSelection all();
  /// The raw inputs of the io blocks (kind "raw"): what a replay plays back.
  static SeriesSelection raw();
  /// The series of block `block` ("<block>.<port>").
  static SeriesSelection block(const std::string& block);
  /// The one series `name`.
  static SeriesSelection one(const std::string& name);
};

/// Reads a whole recording written by Recorder (also one whose writer crashed after a flush).
Expected<Recording> read_recording(const std::string& path);

/// The attributes, the events and the series `selection` wants; the names of the others are
/// in Recording::series_not_read. The memory check counts only what is read.
Expected<Recording> read_recording(const std::string& path, const SeriesSelection& selection);

/// One recording open for reading series by series (a replay's bit-for-bit check holds one
/// series of each file at a time): the file stays open between reads.
class SeriesReader {
 public:
  /// Opens `path` and checks that it is a lodestone recording this build can read.
  static Expected<std::unique_ptr<SeriesReader>> open(const std::string& path);
  ~SeriesReader();
  SeriesReader(const SeriesReader&) = delete;
  SeriesReader& operator=(const SeriesReader&) = delete;

  /// Every series in the file, in the order they were added.
  [[nodiscard]] const std::vector<std::string>& names() const;
  /// Series `name`, whole; what a reader should know about it (see Recording::warnings) is
  /// appended to `warnings`.
  Expected<SeriesData> read(const std::string& name, std::vector<std::string>& warnings);

 private:
  struct Impl;
  explicit SeriesReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// What reading a selection of a recording takes, from the file's layout alone (no data read).
struct ReadCost {
  std::uint64_t bytes = 0;           ///< what read_recording(path, selection) holds at its peak
  std::uint64_t largest_series = 0;  ///< the largest one series read alone takes at its peak
  std::uint64_t rows = 0;            ///< the longest series' rows
};
Expected<ReadCost> read_cost(const std::string& path, const SeriesSelection& selection);

/// read_recording(), read once per process while someone holds the result: a second call for
/// the same file (same device, inode, size and modification time) and the same selection key
/// returns the recording the first one read, without reading the file again. `lode replay`
/// reads a recording's raw series and then configures io.replay blocks that play them back:
/// they share one copy.
Expected<std::shared_ptr<const Recording>> read_recording_shared(const std::string& path);
Expected<std::shared_ptr<const Recording>> read_recording_shared(const std::string& path,
                                                                 const SeriesSelection& selection);

}  // namespace lode::record
