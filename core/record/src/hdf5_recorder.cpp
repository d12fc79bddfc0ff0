// HDF5 recorder: plain 1-D chunked datasets per value, names and units as attributes.
// Layout and reading snippets: core/record/README.md.
#include "lode/record/hdf5_recorder.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

#include "hdf5_common.hpp"
#include "read_in_child.hpp"

namespace lode::record {

using namespace detail;

std::string dataset_name_for(const std::string& element_name, std::size_t index) {
  const bool reserved = std::find_if(kTimeColumns.begin(), kTimeColumns.end(),
                                     [&](const char* column) { return element_name == column; }) != kTimeColumns.end();
  if (!reserved && valid_link_name(element_name)) return element_name;
  if (element_name.empty()) return "value_" + std::to_string(index);
  std::string name = "value_" + element_name;
  std::replace(name.begin(), name.end(), '/', '_');
  return name;
}

// ---- Recorder -----------------------------------------------------------------------------

struct Recorder::Impl {
  struct Series {
    SeriesInfo info;
    Handle group;
    Handle cycle_column, stamp_column, captured_column, time_column;
    std::vector<Handle> value_columns;
    hsize_t chunk_rows = kMaxChunkRows;
    hsize_t rows_written = 0;
    // Rows on disk for certain: those written before the last flush() that succeeded. HDF5
    // writes cached chunks back whenever it needs room, so after a failed write the rows past
    // this may be on disk, fill values, or anything between.
    hsize_t rows_durable = 0;
    hsize_t extent = 0;  // rows every column has room for (Recorder::expect_rows)
    // Rows appended but not yet written, one vector per column.
    std::vector<std::uint64_t> cycle;
    std::vector<std::int64_t> stamp_ns, captured_ns;
    std::vector<std::vector<double>> values;
    std::vector<double> time_s;  // scratch for the write
    std::uint64_t samples = 0, gaps = 0, out_of_order = 0;
    // Recorder::account: the caller's count of missing samples replaces `gaps`, and the
    // samples never due (skipped periods) are written as `skipped`.
    bool accounted = false;
    std::uint64_t accounted_missing = 0, skipped = 0;
    std::uint64_t last_cycle = 0;
    bool has_last_cycle = false;
    bool broken = false;  // a write failed: later rows are dropped (the error was reported)
  };

  std::string path;
  Handle file;
  Handle events_group;
  Handle event_cycle, event_stamp, event_kind, event_text;
  hsize_t events_written = 0;
  std::vector<Recording::Ev> pending_events;
  std::vector<std::unique_ptr<Series>> series;
  hsize_t expected_rows = 0;  // Recorder::expect_rows; 0: unknown
  Status first_error;  // kept until the next flush()/close() returns it
  bool closed = false;

  void fail(const std::string& message) {
    if (first_error.is_ok()) first_error = Status::error("recording '" + path + "': " + message);
  }
  Status take_error() { return std::exchange(first_error, Status::ok()); }

  void write_rows(Series& s) {
    const hsize_t count = s.cycle.size();
    if (count == 0 || s.broken) return;
    s.time_s.resize(count);
    for (hsize_t row = 0; row < count; ++row) s.time_s[row] = static_cast<double>(s.stamp_ns[row]) * 1e-9;
    // A file laid out at its final length (a replay's) is written a whole chunk at a time, as
    // the rows are in memory (write_whole_chunk(), where the host stores the file's
    // little-endian types as they are); its last rows, which start a chunk they do not fill,
    // padded with the fill values to a whole one. Not a recording of unknown length (lode run
    // --record, lode record): on a disk that filled, its file then held rows that were never
    // written, read back as rows (not as the fill values that tell a reader they are missing),
    // where H5Dwrite leaves none.
    const bool whole_chunk = std::endian::native == std::endian::little && expected_rows > 0 &&
                             s.rows_written % s.chunk_rows == 0 &&
                             (count == s.chunk_rows || s.rows_written + count == s.extent);
    if (whole_chunk && count < s.chunk_rows) {
      const std::size_t whole = static_cast<std::size_t>(s.chunk_rows);
      s.cycle.resize(whole, kMissingCycle);
      s.stamp_ns.resize(whole, kMissingStamp);
      s.captured_ns.resize(whole, kMissingStamp);
      s.time_s.resize(whole, kMissingValue);
      for (auto& column : s.values) column.resize(whole, kMissingValue);
    }
    // Every column's elements are 8 bytes, as write_whole_chunk() writes them.
    static_assert(sizeof(std::uint64_t) == 8 && sizeof(std::int64_t) == 8 && sizeof(double) == 8);
    const auto append = [&](hid_t column, hid_t memory_type, const void* data) {
      return whole_chunk ? write_whole_chunk(column, s.rows_written, count, s.chunk_rows, data, s.extent)
                         : append_to_column(column, s.rows_written, count, memory_type, data, s.extent);
    };
    bool ok = append(s.cycle_column.get(), H5T_NATIVE_UINT64, s.cycle.data()) &&
              append(s.stamp_column.get(), H5T_NATIVE_INT64, s.stamp_ns.data()) &&
              append(s.captured_column.get(), H5T_NATIVE_INT64, s.captured_ns.data()) &&
              append(s.time_column.get(), H5T_NATIVE_DOUBLE, s.time_s.data());
    for (std::size_t v = 0; ok && v < s.value_columns.size(); ++v)
      ok = append(s.value_columns[v].get(), H5T_NATIVE_DOUBLE, s.values[v].data());
    if (!ok) {
      fail("cannot write " + std::to_string(count) + " rows of /signals/" + s.info.name + ": " + hdf5_message());
      give_back_to_durable();
    } else {
      s.rows_written += count;
      s.extent = std::max(s.extent, s.rows_written);
    }
    s.cycle.clear();
    s.stamp_ns.clear();
    s.captured_ns.clear();
    for (auto& column : s.values) column.clear();
  }

  // After a failed write or flush: every series ends at the rows its last good flush made
  // durable, and takes no more rows. Shrinking every column there drops rows whose chunks may
  // or may not have reached the disk, so the file never holds fill values among its rows
  // (best effort: on a full disk the shrink itself may not reach the file; the reader then
  // drops the rows past it by their fill values).
  void give_back_to_durable() {
    for (auto& series_ptr : series) {
      Series& s = *series_ptr;
      if (s.broken) continue;
      s.broken = true;
      for (hid_t column : {s.cycle_column.get(), s.stamp_column.get(), s.captured_column.get(), s.time_column.get()})
        H5Dset_extent(column, &s.rows_durable);
      for (const auto& column : s.value_columns) H5Dset_extent(column.get(), &s.rows_durable);
      s.rows_written = s.rows_durable;
      s.extent = s.rows_durable;
    }
  }

  // A series made at its expected length that got fewer rows (a replay that faulted) ends
  // at its last row, not at fill values.
  void trim(Series& s) {
    if (s.broken || s.extent <= s.rows_written) return;
    bool ok = true;
    for (hid_t column : {s.cycle_column.get(), s.stamp_column.get(), s.captured_column.get(), s.time_column.get()})
      ok = H5Dset_extent(column, &s.rows_written) >= 0 && ok;
    for (const auto& column : s.value_columns) ok = H5Dset_extent(column.get(), &s.rows_written) >= 0 && ok;
    if (!ok) fail("cannot shorten /signals/" + s.info.name + " to its " + std::to_string(s.rows_written) + " rows: " +
                  hdf5_message());
    s.extent = s.rows_written;
  }

  void write_events() {
    const hsize_t count = pending_events.size();
    if (count == 0 || !event_cycle.valid()) return;
    std::vector<std::uint64_t> cycles;
    std::vector<std::int64_t> stamps;
    std::vector<const char*> kinds, texts;
    for (const auto& event : pending_events) {
      cycles.push_back(event.cycle);
      stamps.push_back(event.stamp_ns);
      kinds.push_back(event.kind.c_str());
      texts.push_back(event.text.c_str());
    }
    Handle string_type = utf8_string_type();
    // The strings are converted through a buffer that HDF5 allocates and zeroes on every
    // write, 1 MiB unless told: sized to the rows instead (1 MiB zeroed, page by page, for
    // the two events of a replay was a quarter of the CPU time of closing its file).
    Handle transfer(H5Pcreate(H5P_DATASET_XFER));
    H5Pset_buffer(transfer.get(), std::max<std::size_t>(count * 2 * sizeof(hvl_t), 4096), nullptr, nullptr);
    const hid_t strings = transfer.get();
    const bool ok = append_to_column(event_cycle.get(), events_written, count, H5T_NATIVE_UINT64, cycles.data(), events_written) &&
                    append_to_column(event_stamp.get(), events_written, count, H5T_NATIVE_INT64, stamps.data(), events_written) &&
                    append_to_column(event_kind.get(), events_written, count, string_type.get(), kinds.data(), events_written, strings) &&
                    append_to_column(event_text.get(), events_written, count, string_type.get(), texts.data(), events_written, strings);
    if (!ok) {
      fail("cannot write " + std::to_string(count) + " rows of /events: " + hdf5_message());
      for (hid_t column : {event_cycle.get(), event_stamp.get(), event_kind.get(), event_text.get()})
        H5Dset_extent(column, &events_written);  // best effort, as for a series
      event_cycle.reset();  // stop writing events: the columns may now differ in length
    } else {
      events_written += count;
    }
    pending_events.clear();
  }

  // Every object is closed before the file, so H5Fclose really closes it and reports errors.
  void close_file() {
    for (auto& s : series) {
      s->value_columns.clear();
      s->cycle_column.reset();
      s->stamp_column.reset();
      s->captured_column.reset();
      s->time_column.reset();
      s->group.reset();
    }
    event_cycle.reset();
    event_stamp.reset();
    event_kind.reset();
    event_text.reset();
    events_group.reset();
    if (H5Fclose(file.release()) < 0) fail("H5Fclose: " + hdf5_message());
  }

  void write_counters(Series& s) {
    for (const auto& [key, value] : {std::pair{"samples", static_cast<std::uint64_t>(s.rows_written)},
                                     std::pair{"gaps", gaps_of(s)}, std::pair{"out_of_order", s.out_of_order}}) {
      if (Status status = update_counter_attribute(s.group.get(), key, value); !status) {
        fail("/signals/" + s.info.name + ": " + status.message());
      }
    }
    if (s.accounted) {
      if (Status status = update_counter_attribute(s.group.get(), "skipped", s.skipped); !status)
        fail("/signals/" + s.info.name + ": " + status.message());
    }
  }

  static std::uint64_t gaps_of(const Series& s) { return s.accounted ? s.accounted_missing : s.gaps; }
};

namespace {
/// Why H5Fcreate failed, in the user's words where the cause is a common one (HDF5 says
/// "unable to create file: unable to open file: name = ..., errno = 2, ...").
std::string why_not_created(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const std::string folder = parent.empty() ? std::string(".") : parent.string();
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) return "the folder " + folder + " does not exist";
  if (std::filesystem::is_directory(path, ec)) return "it is a folder";
  if (::access(folder.c_str(), W_OK) != 0) return "the folder " + folder + " is not writable by this user";
  return hdf5_message();
}
}  // namespace

Recorder::Recorder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Recorder::~Recorder() { (void)close(); }

Expected<std::unique_ptr<Recorder>> Recorder::create(const std::string& path, const std::string& source) {
  silence_hdf5_errors();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  // A file already there is replaced rather than truncated: ext4 (its auto_da_alloc default)
  // starts writing a file that was truncated and written again out to disk when it is closed,
  // inside the close (the close() of a replay's file written over the previous replay's was
  // half of H5Fclose's time). Only a plain file with one name: through a symbolic link or a
  // second hard link the file itself is still truncated and written.
  struct stat existing {};
  if (::lstat(path.c_str(), &existing) == 0 && S_ISREG(existing.st_mode) && existing.st_nlink == 1)
    (void)::unlink(path.c_str());
  impl->file = Handle(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
  if (!impl->file.valid()) {
    return Status::error("recording '" + path + "': cannot create the file: " + why_not_created(path));
  }
  const hid_t root = impl->file.get();
  const std::int32_t version = kFormatVersion;
  for (Status status :
       {write_text_attribute(root, "format", kFormat),
        write_number_attribute(root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT32, &version),
        write_text_attribute(root, "source", source), write_text_attribute(root, "created_utc", utc_now())}) {
    if (!status) return Status::error("recording '" + path + "': " + status.message());
  }
  // /signals tracks creation order so a reader lists the series in the order they were added.
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE));
  H5Pset_link_creation_order(gcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  Handle signals(H5Gcreate2(root, "signals", H5P_DEFAULT, gcpl.get(), H5P_DEFAULT));
  impl->events_group = Handle(H5Gcreate2(root, "events", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (!signals.valid() || !impl->events_group.valid()) {
    return Status::error("recording '" + path + "': cannot create /signals or /events: " + hdf5_message());
  }
  Handle string_type = utf8_string_type();
  const hid_t events = impl->events_group.get();
  impl->event_cycle = create_column(events, "cycle", H5T_STD_U64LE, kEventChunkRows, H5T_NATIVE_UINT64, &kMissingCycle);
  impl->event_stamp = create_column(events, "stamp_ns", H5T_STD_I64LE, kEventChunkRows);
  impl->event_kind = create_column(events, "kind", string_type.get(), kEventChunkRows);
  impl->event_text = create_column(events, "text", string_type.get(), kEventChunkRows);
  if (!impl->event_cycle.valid() || !impl->event_stamp.valid() || !impl->event_kind.valid() ||
      !impl->event_text.valid()) {
    return Status::error("recording '" + path + "': cannot create the /events datasets: " + hdf5_message());
  }
  return std::unique_ptr<Recorder>(new Recorder(std::move(impl)));
}

void Recorder::set_attribute(const std::string& key, const std::string& value) {
  silence_hdf5_errors();
  if (impl_->closed) return impl_->fail("set_attribute('" + key + "') after close()");
  if (key.empty()) return impl_->fail("set_attribute: empty key");
  if (Status status = write_text_attribute(impl_->file.get(), key, value); !status) impl_->fail(status.message());
}

void Recorder::set_attribute(const std::string& key, double value) {
  silence_hdf5_errors();
  if (impl_->closed) return impl_->fail("set_attribute('" + key + "') after close()");
  if (key.empty()) return impl_->fail("set_attribute: empty key");
  if (Status status = write_number_attribute(impl_->file.get(), key, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
      !status) {
    impl_->fail(status.message());
  }
}

Expected<int> Recorder::add_series(const SeriesInfo& info) {
  silence_hdf5_errors();
  const std::string where = "recording '" + impl_->path + "': series '" + info.name + "': ";
  if (impl_->closed) return Status::error(where + "add_series after close()");
  if (!valid_link_name(info.name)) {
    return Status::error(where + "name must be non-empty, not \".\" and without '/'");
  }
  if (info.kind != "signal" && info.kind != "state" && info.kind != "raw") {
    return Status::error(where + "kind '" + info.kind + "' is not one of signal, state, raw");
  }
  if (info.names.empty()) return Status::error(where + "names is empty (a series needs at least one value)");
  if (info.names.size() != info.units.size()) {
    return Status::error(where + "names has " + std::to_string(info.names.size()) + " entries but units has " +
                         std::to_string(info.units.size()));
  }
  if (info.decimation == 0) return Status::error(where + "decimation must be at least 1");
  if (!(info.rate_hz >= 0) || !(info.pipeline_rate_hz >= 0)) {
    return Status::error(where + "rate_hz and pipeline_rate_hz must be >= 0 (0 = unknown)");
  }
  std::set<std::string> element_names, dataset_names;
  for (std::size_t i = 0; i < info.names.size(); ++i) {
    if (!element_names.insert(info.names[i]).second) {
      return Status::error(where + "names: '" + info.names[i] + "' appears twice");
    }
    const std::string dataset = dataset_name_for(info.names[i], i);
    if (!dataset_names.insert(dataset).second) {
      return Status::error(where + "names: '" + info.names[i] + "' would be stored as '" + dataset +
                           "', which another element already uses");
    }
  }
  Handle signals(H5Gopen2(impl_->file.get(), "signals", H5P_DEFAULT));
  if (H5Lexists(signals.get(), info.name.c_str(), H5P_DEFAULT) > 0) {
    return Status::error(where + "a series of this name already exists");
  }

  auto s = std::make_unique<Impl::Series>();
  s->info = info;
  s->chunk_rows = chunk_rows_for(info.rate_hz);
  // Known length: the datasets are made at their final size (no H5Dset_extent per chunk) in
  // larger chunks, written without HDF5's chunk cache (each chunk is written once, whole).
  const bool known_length = impl_->expected_rows > 0;
  if (known_length) {
    s->chunk_rows = std::min(impl_->expected_rows, kKnownLengthChunkRows);
    s->extent = impl_->expected_rows;
  }
  Handle lcpl = utf8_link_properties();
  s->group = Handle(H5Gcreate2(signals.get(), info.name.c_str(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!s->group.valid()) return Status::error(where + "cannot create the group: " + hdf5_message());
  // A series is all or nothing: a half-built group would make the file unreadable.
  const auto create_objects = [&]() -> Status {
    const hid_t group = s->group.get();
    const std::uint64_t zero = 0;
    for (Status status :
         {write_text_attribute(group, "topic", info.topic), write_text_attribute(group, "kind", info.kind),
          write_number_attribute(group, "rate_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &info.rate_hz),
          write_number_attribute(group, "pipeline_rate_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &info.pipeline_rate_hz),
          write_number_attribute(group, "decimation", H5T_STD_U32LE, H5T_NATIVE_UINT32, &info.decimation),
          write_text_array_attribute(group, "names", info.names),
          write_text_array_attribute(group, "units", info.units),
          write_number_attribute(group, "samples", H5T_STD_U64LE, H5T_NATIVE_UINT64, &zero),
          write_number_attribute(group, "gaps", H5T_STD_U64LE, H5T_NATIVE_UINT64, &zero),
          write_number_attribute(group, "out_of_order", H5T_STD_U64LE, H5T_NATIVE_UINT64, &zero)}) {
      if (!status) return status;
    }

    const hsize_t rows = s->extent;
    const bool cache = !known_length;
    s->cycle_column = create_column(group, "cycle", H5T_STD_U64LE, s->chunk_rows, H5T_NATIVE_UINT64, &kMissingCycle,
                                    rows, cache);
    s->stamp_column = create_column(group, "stamp_ns", H5T_STD_I64LE, s->chunk_rows, H5T_NATIVE_INT64, &kMissingStamp,
                                    rows, cache);
    s->captured_column = create_column(group, "captured_ns", H5T_STD_I64LE, s->chunk_rows, H5T_NATIVE_INT64,
                                       &kMissingStamp, rows, cache);
    s->time_column = create_column(group, "time_s", H5T_IEEE_F64LE, s->chunk_rows, H5T_NATIVE_DOUBLE, &kMissingValue,
                                   rows, cache);
    if (!s->cycle_column.valid() || !s->stamp_column.valid() || !s->captured_column.valid() ||
        !s->time_column.valid()) {
      return Status::error("cannot create the time datasets: " + hdf5_message());
    }
    for (const auto& [column, unit] :
         {std::pair{s->stamp_column.get(), "ns"}, std::pair{s->captured_column.get(), "ns"},
          std::pair{s->time_column.get(), "s"}}) {
      if (Status status = write_text_attribute(column, "unit", unit); !status) return status;
    }
    for (std::size_t i = 0; i < info.names.size(); ++i) {
      const std::string dataset = dataset_name_for(info.names[i], i);
      Handle column = create_column(group, dataset, H5T_IEEE_F64LE, s->chunk_rows, H5T_NATIVE_DOUBLE, &kMissingValue,
                                    rows, cache);
      if (!column.valid()) return Status::error("cannot create dataset '" + dataset + "': " + hdf5_message());
      for (Status status : {write_text_attribute(column.get(), "unit", info.units[i]),
                            write_text_attribute(column.get(), "name", info.names[i])}) {
        if (!status) return Status::error("dataset '" + dataset + "': " + status.message());
      }
      s->value_columns.push_back(std::move(column));
    }
    return {};
  };
  if (Status status = create_objects(); !status) {
    s.reset();
    H5Ldelete(signals.get(), info.name.c_str(), H5P_DEFAULT);
    H5Eclear2(H5E_DEFAULT);
    return Status::error(where + status.message());
  }
  s->values.resize(info.names.size());
  for (auto& column : s->values) column.reserve(s->chunk_rows);
  s->cycle.reserve(s->chunk_rows);
  s->stamp_ns.reserve(s->chunk_rows);
  s->captured_ns.reserve(s->chunk_rows);

  impl_->series.push_back(std::move(s));
  return static_cast<int>(impl_->series.size() - 1);
}

void Recorder::append(int series, std::uint64_t cycle, std::int64_t stamp_ns, std::int64_t captured_ns,
                      const double* values) {
  if (impl_->closed) return impl_->fail("append after close()");
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) {
    return impl_->fail("append to unknown series " + std::to_string(series));
  }
  Impl::Series& s = *impl_->series[static_cast<std::size_t>(series)];
  if (s.broken) return;
  if (s.has_last_cycle) {
    if (cycle <= s.last_cycle) {
      ++s.out_of_order;
    } else {
      const std::uint64_t step = cycle - s.last_cycle;
      // ceil(step / decimation) - 1 samples were due in between and never came.
      s.gaps += (step + s.info.decimation - 1) / s.info.decimation - 1;
    }
  }
  s.last_cycle = cycle;
  s.has_last_cycle = true;
  ++s.samples;
  s.cycle.push_back(cycle);
  s.stamp_ns.push_back(stamp_ns);
  s.captured_ns.push_back(captured_ns);
  for (std::size_t v = 0; v < s.values.size(); ++v) s.values[v].push_back(values[v]);
  // Write when the file reaches a chunk boundary, so chunks stay whole even after a flush().
  if ((s.rows_written + s.cycle.size()) % s.chunk_rows == 0) {
    silence_hdf5_errors();
    impl_->write_rows(s);
  }
}

void Recorder::expect_rows(std::uint64_t rows) { impl_->expected_rows = rows; }

void Recorder::append_rows(int series, std::size_t count, const std::uint64_t* cycle, const std::int64_t* stamp_ns,
                           const double* values, std::size_t stride) {
  if (impl_->closed) return impl_->fail("append after close()");
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) {
    return impl_->fail("append to unknown series " + std::to_string(series));
  }
  Impl::Series& s = *impl_->series[static_cast<std::size_t>(series)];
  const std::size_t width = s.values.size();
  std::size_t done = 0;
  while (done < count && !s.broken) {
    // Up to the next chunk boundary, column by column (rows in, columns out).
    const std::size_t buffered = s.cycle.size();
    const std::size_t room = static_cast<std::size_t>(s.chunk_rows - (s.rows_written + buffered) % s.chunk_rows);
    const std::size_t n = std::min(room, count - done);
    for (std::size_t r = done; r < done + n; ++r) {
      if (s.has_last_cycle) {
        if (cycle[r] <= s.last_cycle) {
          ++s.out_of_order;
        } else {
          s.gaps += (cycle[r] - s.last_cycle + s.info.decimation - 1) / s.info.decimation - 1;
        }
      }
      s.last_cycle = cycle[r];
      s.has_last_cycle = true;
    }
    s.samples += n;
    s.cycle.insert(s.cycle.end(), cycle + done, cycle + done + n);
    s.stamp_ns.insert(s.stamp_ns.end(), stamp_ns + done, stamp_ns + done + n);
    s.captured_ns.resize(buffered + n, 0);
    for (std::size_t v = 0; v < width; ++v) {
      auto& column = s.values[v];
      column.resize(buffered + n);
      const double* from = values + done * stride + v;
      for (std::size_t r = 0; r < n; ++r) column[buffered + r] = from[r * stride];
    }
    done += n;
    if ((s.rows_written + s.cycle.size()) % s.chunk_rows == 0) {
      silence_hdf5_errors();
      impl_->write_rows(s);
    }
  }
}

void Recorder::add_event(std::uint64_t cycle, std::int64_t stamp_ns, const std::string& kind, const std::string& text) {
  if (impl_->closed) return impl_->fail("add_event('" + kind + "') after close()");
  impl_->pending_events.push_back({cycle, stamp_ns, kind, text});
  if (impl_->pending_events.size() >= kEventChunkRows) {
    silence_hdf5_errors();
    impl_->write_events();
  }
}

Status Recorder::flush() {
  silence_hdf5_errors();
  if (impl_->closed) return Status::error("recording '" + impl_->path + "': flush after close()");
  for (auto& s : impl_->series) {
    impl_->write_rows(*s);
    impl_->write_counters(*s);
  }
  impl_->write_events();
  if (H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL) < 0) {
    impl_->fail("H5Fflush: " + hdf5_message());
    impl_->give_back_to_durable();
  }
  if (impl_->first_error.is_ok())
    for (auto& s : impl_->series) s->rows_durable = s->rows_written;
  return impl_->take_error();
}

Status Recorder::close() {
  if (impl_->closed) return impl_->take_error();
  silence_hdf5_errors();
  for (auto& s : impl_->series) {
    impl_->write_rows(*s);
    impl_->trim(*s);
    impl_->write_counters(*s);
  }
  impl_->write_events();
  impl_->closed = true;
  impl_->close_file();
  Status status = impl_->take_error();
  if (status) trust_written_file(impl_->path);  // read back by this process without a check
  return status;
}

std::uint64_t Recorder::samples(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return impl_->series[static_cast<std::size_t>(series)]->samples;
}

std::uint64_t Recorder::gaps(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return Impl::gaps_of(*impl_->series[static_cast<std::size_t>(series)]);
}

void Recorder::account(int series, std::uint64_t missing, std::uint64_t skipped) {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) {
    return impl_->fail("account for unknown series " + std::to_string(series));
  }
  Impl::Series& s = *impl_->series[static_cast<std::size_t>(series)];
  s.accounted = true;
  s.accounted_missing = missing;
  s.skipped = skipped;
}

std::uint64_t Recorder::out_of_order(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return impl_->series[static_cast<std::size_t>(series)]->out_of_order;
}

const std::string& Recorder::path() const { return impl_->path; }

}  // namespace lode::record
