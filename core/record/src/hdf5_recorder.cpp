// HDF5 recorder: plain 1-D chunked datasets per value, names and units as attributes.
// Layout and reading snippets: core/record/README.md.
#include "lode/record/hdf5_recorder.hpp"

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <limits>
#include <set>
#include <utility>

namespace lode::record {
namespace {

constexpr const char* kFormat = "lodestone-recording";
constexpr int kFormatVersion = 1;
constexpr hsize_t kMaxChunkRows = 4096;
constexpr hsize_t kMinChunkRows = 64;
constexpr hsize_t kEventChunkRows = 256;
constexpr std::array<const char*, 4> kTimeColumns = {"cycle", "stamp_ns", "captured_ns", "time_s"};

// ---- HDF5 plumbing ------------------------------------------------------------------------

// HDF5 prints its error stack to stderr by default; errors become Status messages instead.
// The setting is per thread in the thread-safe build, so every entry point calls this.
//
// The first call also tells HDF5 not to install its atexit() clean-up, before anything else
// initialises the library. Every file this code opens it closes itself; the clean-up only
// ever matters for objects HDF5 could not close, and with those it crashes: after a write
// failed (a full disk) the datasets stay open, and closing them at exit dies of SIGSEGV in
// H5D_close, taking the run's exit status and summary with it.
void silence_hdf5_errors() {
  static const bool no_atexit = [] { return H5dont_atexit() >= 0; }();
  (void)no_atexit;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

herr_t collect_error(unsigned /*depth*/, const H5E_error2_t* error, void* data) {
  auto* descriptions = static_cast<std::vector<std::string>*>(data);
  if (error->desc != nullptr && *error->desc != '\0' &&
      (descriptions->empty() || descriptions->back() != error->desc)) {
    descriptions->emplace_back(error->desc);
  }
  return 0;
}

/// The failed call's HDF5 error stack as "outermost: innermost" (the middle entries repeat
/// "unable to open file"), on one line, then cleared.
std::string hdf5_message() {
  std::vector<std::string> descriptions;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect_error, &descriptions);
  H5Eclear2(H5E_DEFAULT);
  if (descriptions.empty()) return "unknown HDF5 error";
  std::string text = descriptions.front();
  if (descriptions.size() > 1) text += ": " + descriptions.back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  // The POSIX driver's text carries the whole write call ("file write failed: time = ...,
  // filename = ..., errno = 28, error message = 'No space left on device', buf = ...");
  // what a user needs of it is the error message.
  const std::string marker = "error message = '";
  if (const auto at = text.find(marker); at != std::string::npos) {
    const auto end = text.find('\'', at + marker.size());
    const std::string reason = text.substr(at + marker.size(), end == std::string::npos ? std::string::npos
                                                                                       : end - at - marker.size());
    const auto cut = text.find(": time = ");
    text = (cut == std::string::npos ? text.substr(0, at) : text.substr(0, cut)) + ": " + reason;
  }
  return text;
}

/// Owns one HDF5 identifier (file, group, dataset, dataspace, type, property list, attribute).
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, H5I_INVALID_HID)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, H5I_INVALID_HID);
    }
    return *this;
  }
  void reset() {
    if (id_ >= 0) H5Idec_ref(id_);
    id_ = H5I_INVALID_HID;
  }
  [[nodiscard]] hid_t get() const { return id_; }
  [[nodiscard]] hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }
  [[nodiscard]] bool valid() const { return id_ >= 0; }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

Handle utf8_string_type() {
  Handle type(H5Tcopy(H5T_C_S1));
  H5Tset_size(type.get(), H5T_VARIABLE);
  H5Tset_cset(type.get(), H5T_CSET_UTF8);
  return type;
}

// Link and attribute names are flagged UTF-8 so "θ" reads back as "θ" in Python and MATLAB.
Handle utf8_link_properties() {
  Handle properties(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_char_encoding(properties.get(), H5T_CSET_UTF8);
  return properties;
}

Handle utf8_attribute_properties() {
  Handle properties(H5Pcreate(H5P_ATTRIBUTE_CREATE));
  H5Pset_char_encoding(properties.get(), H5T_CSET_UTF8);
  return properties;
}

/// Opens attribute `key` of `object` for writing with `file_type` and `space`, replacing an
/// attribute of the same name (set_attribute twice keeps the last value).
Handle fresh_attribute(hid_t object, const std::string& key, hid_t file_type, hid_t space) {
  if (H5Aexists(object, key.c_str()) > 0) H5Adelete(object, key.c_str());
  Handle acpl = utf8_attribute_properties();
  return Handle(H5Acreate2(object, key.c_str(), file_type, space, acpl.get(), H5P_DEFAULT));
}

Status write_text_attribute(hid_t object, const std::string& key, const std::string& value) {
  Handle type = utf8_string_type();
  Handle space(H5Screate(H5S_SCALAR));
  Handle attribute = fresh_attribute(object, key, type.get(), space.get());
  const char* text = value.c_str();
  if (!attribute.valid() || H5Awrite(attribute.get(), type.get(), &text) < 0) {
    return Status::error("attribute '" + key + "': " + hdf5_message());
  }
  return {};
}

Status write_text_array_attribute(hid_t object, const std::string& key, const std::vector<std::string>& values) {
  Handle type = utf8_string_type();
  const hsize_t count = values.size();
  Handle space(H5Screate_simple(1, &count, nullptr));
  Handle attribute = fresh_attribute(object, key, type.get(), space.get());
  std::vector<const char*> texts;
  texts.reserve(values.size());
  for (const auto& value : values) texts.push_back(value.c_str());
  if (!attribute.valid() || H5Awrite(attribute.get(), type.get(), texts.data()) < 0) {
    return Status::error("attribute '" + key + "': " + hdf5_message());
  }
  return {};
}

Status write_number_attribute(hid_t object, const std::string& key, hid_t file_type, hid_t memory_type,
                              const void* value) {
  Handle space(H5Screate(H5S_SCALAR));
  Handle attribute = fresh_attribute(object, key, file_type, space.get());
  if (!attribute.valid() || H5Awrite(attribute.get(), memory_type, value) < 0) {
    return Status::error("attribute '" + key + "': " + hdf5_message());
  }
  return {};
}

/// Rewrites an existing scalar attribute in place (the counters, refreshed at every flush:
/// no delete/create, so the object header does not grow).
Status update_counter_attribute(hid_t object, const char* key, std::uint64_t value) {
  if (H5Aexists(object, key) <= 0) {
    return write_number_attribute(object, key, H5T_STD_U64LE, H5T_NATIVE_UINT64, &value);
  }
  Handle attribute(H5Aopen(object, key, H5P_DEFAULT));
  if (!attribute.valid() || H5Awrite(attribute.get(), H5T_NATIVE_UINT64, &value) < 0) {
    return Status::error(std::string("attribute '") + key + "': " + hdf5_message());
  }
  return {};
}

/// What a row reads as where the file has no data for it: space the writer reserved (the
/// extent grew) but whose chunk never reached the disk, after a crash or a full disk. Chosen
/// so such rows cannot pass for data: no cycle is UINT64_MAX, and a value column reads NaN,
/// not a plausible 0.0.
constexpr std::uint64_t kMissingCycle = ~std::uint64_t{0};
constexpr std::int64_t kMissingStamp = std::numeric_limits<std::int64_t>::min();
constexpr double kMissingValue = std::numeric_limits<double>::quiet_NaN();

/// An empty 1-D dataset that grows without limit, chunked by `chunk_rows`; `fill` (of
/// `fill_type`, in memory) is what unwritten rows read as (nullptr: HDF5's default).
Handle create_column(hid_t group, const std::string& name, hid_t file_type, hsize_t chunk_rows,
                     hid_t fill_type = -1, const void* fill = nullptr) {
  const hsize_t initial = 0;
  const hsize_t unlimited = H5S_UNLIMITED;
  Handle space(H5Screate_simple(1, &initial, &unlimited));
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
  H5Pset_chunk(dcpl.get(), 1, &chunk_rows);
  if (fill != nullptr) H5Pset_fill_value(dcpl.get(), fill_type, fill);
  Handle lcpl = utf8_link_properties();
  return Handle(H5Dcreate2(group, name.c_str(), file_type, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT));
}

/// Extends `dataset` from `old_rows` by `count` rows and writes them from `data`.
bool append_to_column(hid_t dataset, hsize_t old_rows, hsize_t count, hid_t memory_type, const void* data) {
  const hsize_t new_rows = old_rows + count;
  if (H5Dset_extent(dataset, &new_rows) < 0) return false;
  Handle file_space(H5Dget_space(dataset));
  if (!file_space.valid() ||
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, &old_rows, nullptr, &count, nullptr) < 0) {
    return false;
  }
  Handle memory_space(H5Screate_simple(1, &count, nullptr));
  return H5Dwrite(dataset, memory_type, memory_space.get(), file_space.get(), H5P_DEFAULT, data) >= 0;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> text{};
  std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text.data();
}

bool valid_link_name(const std::string& name) {
  return !name.empty() && name != "." && name.find('/') == std::string::npos;
}

hsize_t chunk_rows_for(double rate_hz) {
  hsize_t rows = kMaxChunkRows;
  if (rate_hz > 0 && std::isfinite(rate_hz)) {
    rows = std::min<hsize_t>(kMaxChunkRows, static_cast<hsize_t>(std::ceil(rate_hz)));  // 1 s
  }
  return std::max(rows, kMinChunkRows);
}

}  // namespace

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
    // Rows appended but not yet written, one vector per column.
    std::vector<std::uint64_t> cycle;
    std::vector<std::int64_t> stamp_ns, captured_ns;
    std::vector<std::vector<double>> values;
    std::vector<double> time_s;  // scratch for the write
    std::uint64_t samples = 0, gaps = 0, out_of_order = 0;
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
    bool ok =
        append_to_column(s.cycle_column.get(), s.rows_written, count, H5T_NATIVE_UINT64, s.cycle.data()) &&
        append_to_column(s.stamp_column.get(), s.rows_written, count, H5T_NATIVE_INT64, s.stamp_ns.data()) &&
        append_to_column(s.captured_column.get(), s.rows_written, count, H5T_NATIVE_INT64, s.captured_ns.data()) &&
        append_to_column(s.time_column.get(), s.rows_written, count, H5T_NATIVE_DOUBLE, s.time_s.data());
    for (std::size_t v = 0; ok && v < s.value_columns.size(); ++v) {
      ok = append_to_column(s.value_columns[v].get(), s.rows_written, count, H5T_NATIVE_DOUBLE, s.values[v].data());
    }
    if (!ok) {
      s.broken = true;
      fail("cannot write " + std::to_string(count) + " rows of /signals/" + s.info.name + ": " + hdf5_message());
      // Give back the rows this write reserved, so every column ends at the last row written
      // (best effort: on a full disk the shrink itself may not reach the file, and then the
      // reader drops the reserved rows by their fill values).
      for (hid_t column : {s.cycle_column.get(), s.stamp_column.get(), s.captured_column.get(), s.time_column.get()})
        H5Dset_extent(column, &s.rows_written);
      for (const auto& column : s.value_columns) H5Dset_extent(column.get(), &s.rows_written);
    } else {
      s.rows_written += count;
    }
    s.cycle.clear();
    s.stamp_ns.clear();
    s.captured_ns.clear();
    for (auto& column : s.values) column.clear();
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
    const bool ok = append_to_column(event_cycle.get(), events_written, count, H5T_NATIVE_UINT64, cycles.data()) &&
                    append_to_column(event_stamp.get(), events_written, count, H5T_NATIVE_INT64, stamps.data()) &&
                    append_to_column(event_kind.get(), events_written, count, string_type.get(), kinds.data()) &&
                    append_to_column(event_text.get(), events_written, count, string_type.get(), texts.data());
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
                                     std::pair{"gaps", s.gaps}, std::pair{"out_of_order", s.out_of_order}}) {
      if (Status status = update_counter_attribute(s.group.get(), key, value); !status) {
        fail("/signals/" + s.info.name + ": " + status.message());
      }
    }
  }
};

Recorder::Recorder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Recorder::~Recorder() { (void)close(); }

Expected<std::unique_ptr<Recorder>> Recorder::create(const std::string& path, const std::string& source) {
  silence_hdf5_errors();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->file = Handle(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
  if (!impl->file.valid()) {
    return Status::error("recording '" + path + "': cannot create the file: " + hdf5_message());
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

    s->cycle_column = create_column(group, "cycle", H5T_STD_U64LE, s->chunk_rows, H5T_NATIVE_UINT64, &kMissingCycle);
    s->stamp_column = create_column(group, "stamp_ns", H5T_STD_I64LE, s->chunk_rows, H5T_NATIVE_INT64, &kMissingStamp);
    s->captured_column =
        create_column(group, "captured_ns", H5T_STD_I64LE, s->chunk_rows, H5T_NATIVE_INT64, &kMissingStamp);
    s->time_column = create_column(group, "time_s", H5T_IEEE_F64LE, s->chunk_rows, H5T_NATIVE_DOUBLE, &kMissingValue);
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
      Handle column = create_column(group, dataset, H5T_IEEE_F64LE, s->chunk_rows, H5T_NATIVE_DOUBLE, &kMissingValue);
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
  if (H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL) < 0) impl_->fail("H5Fflush: " + hdf5_message());
  return impl_->take_error();
}

Status Recorder::close() {
  if (impl_->closed) return impl_->take_error();
  silence_hdf5_errors();
  for (auto& s : impl_->series) {
    impl_->write_rows(*s);
    impl_->write_counters(*s);
  }
  impl_->write_events();
  impl_->closed = true;
  impl_->close_file();
  return impl_->take_error();
}

std::uint64_t Recorder::samples(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return impl_->series[static_cast<std::size_t>(series)]->samples;
}

std::uint64_t Recorder::gaps(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return impl_->series[static_cast<std::size_t>(series)]->gaps;
}

std::uint64_t Recorder::out_of_order(int series) const {
  if (series < 0 || static_cast<std::size_t>(series) >= impl_->series.size()) return 0;
  return impl_->series[static_cast<std::size_t>(series)]->out_of_order;
}

const std::string& Recorder::path() const { return impl_->path; }

// ---- Reading ------------------------------------------------------------------------------

namespace {

/// Every string of a string attribute or dataset (scalar or 1-D, variable or fixed length).
template <typename Read>
Expected<std::vector<std::string>> read_strings(hid_t file_type, hid_t space, Read&& read) {
  const hssize_t count = H5Sget_simple_extent_npoints(space);
  if (count < 0) return Status::error(hdf5_message());
  std::vector<std::string> strings;
  strings.reserve(static_cast<std::size_t>(count));
  if (H5Tis_variable_str(file_type) > 0) {
    Handle memory_type = utf8_string_type();
    std::vector<char*> texts(static_cast<std::size_t>(count), nullptr);
    if (count > 0 && read(memory_type.get(), texts.data()) < 0) return Status::error(hdf5_message());
    for (char* text : texts) strings.emplace_back(text != nullptr ? text : "");
    if (count > 0) H5Dvlen_reclaim(memory_type.get(), space, H5P_DEFAULT, texts.data());
    return strings;
  }
  const std::size_t size = H5Tget_size(file_type);
  Handle memory_type(H5Tcopy(H5T_C_S1));
  H5Tset_size(memory_type.get(), size);
  std::vector<char> buffer(size * static_cast<std::size_t>(count) + 1, '\0');
  if (count > 0 && read(memory_type.get(), buffer.data()) < 0) return Status::error(hdf5_message());
  for (hssize_t i = 0; i < count; ++i) {
    const char* begin = buffer.data() + static_cast<std::size_t>(i) * size;
    strings.emplace_back(begin, std::find(begin, begin + size, '\0'));
  }
  return strings;
}

Expected<std::vector<std::string>> read_string_attribute(hid_t object, const char* key) {
  Handle attribute(H5Aopen(object, key, H5P_DEFAULT));
  if (!attribute.valid()) return Status::error(std::string("attribute '") + key + "' is missing");
  Handle type(H5Aget_type(attribute.get()));
  Handle space(H5Aget_space(attribute.get()));
  if (H5Tget_class(type.get()) != H5T_STRING) return Status::error(std::string("attribute '") + key + "' is not text");
  auto strings = read_strings(type.get(), space.get(),
                              [&](hid_t memory_type, void* out) { return H5Aread(attribute.get(), memory_type, out); });
  if (!strings) return Status::error(std::string("attribute '") + key + "': " + strings.error());
  return strings;
}

Expected<std::string> read_text_attribute(hid_t object, const char* key) {
  auto strings = read_string_attribute(object, key);
  if (!strings) return strings.status();
  if (strings->size() != 1) return Status::error(std::string("attribute '") + key + "' is not a single string");
  return strings->front();
}

/// A scalar numeric attribute converted by HDF5 to `memory_type`.
template <typename T>
Expected<T> read_number_attribute(hid_t object, const char* key, hid_t memory_type) {
  Handle attribute(H5Aopen(object, key, H5P_DEFAULT));
  if (!attribute.valid()) return Status::error(std::string("attribute '") + key + "' is missing");
  T value{};
  if (H5Aread(attribute.get(), memory_type, &value) < 0) {
    return Status::error(std::string("attribute '") + key + "': " + hdf5_message());
  }
  return value;
}

template <typename T>
Expected<std::vector<T>> read_column(hid_t group, const std::string& name, hid_t memory_type) {
  Handle dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT));
  if (!dataset.valid()) return Status::error("dataset '" + name + "' is missing");
  Handle space(H5Dget_space(dataset.get()));
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count < 0) return Status::error("dataset '" + name + "': " + hdf5_message());
  std::vector<T> values(static_cast<std::size_t>(count));
  if (count > 0 && H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0) {
    return Status::error("dataset '" + name + "': " + hdf5_message());
  }
  return values;
}

Expected<std::vector<std::string>> read_string_column(hid_t group, const std::string& name) {
  Handle dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT));
  if (!dataset.valid()) return Status::error("dataset '" + name + "' is missing");
  Handle type(H5Dget_type(dataset.get()));
  Handle space(H5Dget_space(dataset.get()));
  auto strings = read_strings(type.get(), space.get(), [&](hid_t memory_type, void* out) {
    return H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out);
  });
  if (!strings) return Status::error("dataset '" + name + "': " + strings.error());
  return strings;
}

struct RootAttributes {
  Recording* recording;
  std::string error;
};

herr_t collect_root_attribute(hid_t object, const char* key, const H5A_info_t* /*info*/, void* data) {
  auto* out = static_cast<RootAttributes*>(data);
  Handle attribute(H5Aopen(object, key, H5P_DEFAULT));
  Handle type(H5Aget_type(attribute.get()));
  Handle space(H5Aget_space(attribute.get()));
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (type_class == H5T_STRING) {
    auto text = read_text_attribute(object, key);
    if (!text) {
      out->error = text.error();
      return -1;
    }
    out->recording->text_attributes[key] = *text;
  } else if ((type_class == H5T_INTEGER || type_class == H5T_FLOAT) && H5Sget_simple_extent_npoints(space.get()) == 1) {
    double value = 0;
    if (H5Aread(attribute.get(), H5T_NATIVE_DOUBLE, &value) < 0) {
      out->error = std::string("attribute '") + key + "': " + hdf5_message();
      return -1;
    }
    out->recording->number_attributes[key] = value;
  }  // other attributes (arrays, compounds added by other tools) are not part of the format
  return 0;
}

herr_t collect_link_name(hid_t /*group*/, const char* name, const H5L_info_t* /*info*/, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}

Expected<SeriesData> read_series(hid_t signals, const std::string& name, std::vector<std::string>& warnings) {
  const std::string where = "/signals/" + name + ": ";
  Handle group(H5Gopen2(signals, name.c_str(), H5P_DEFAULT));
  if (!group.valid()) return Status::error(where + "not a group: " + hdf5_message());
  const hid_t g = group.get();
  SeriesData data;
  data.info.name = name;
  auto topic = read_text_attribute(g, "topic");
  auto kind = read_text_attribute(g, "kind");
  auto names = read_string_attribute(g, "names");
  auto units = read_string_attribute(g, "units");
  auto rate = read_number_attribute<double>(g, "rate_hz", H5T_NATIVE_DOUBLE);
  auto pipeline_rate = read_number_attribute<double>(g, "pipeline_rate_hz", H5T_NATIVE_DOUBLE);
  auto decimation = read_number_attribute<std::uint32_t>(g, "decimation", H5T_NATIVE_UINT32);
  auto gaps = read_number_attribute<std::uint64_t>(g, "gaps", H5T_NATIVE_UINT64);
  auto out_of_order = read_number_attribute<std::uint64_t>(g, "out_of_order", H5T_NATIVE_UINT64);
  for (const Status& status : {topic.status(), kind.status(), names.status(), units.status(), rate.status(),
                               pipeline_rate.status(), decimation.status(), gaps.status(), out_of_order.status()}) {
    if (!status) return Status::error(where + status.message());
  }
  if (names->size() != units->size()) return Status::error(where + "attributes names and units differ in length");
  data.info.topic = *topic;
  data.info.kind = *kind;
  data.info.names = *names;
  data.info.units = *units;
  data.info.rate_hz = *rate;
  data.info.pipeline_rate_hz = *pipeline_rate;
  data.info.decimation = *decimation;
  data.gaps = *gaps;
  data.out_of_order = *out_of_order;

  auto cycle = read_column<std::uint64_t>(g, "cycle", H5T_NATIVE_UINT64);
  auto stamp = read_column<std::int64_t>(g, "stamp_ns", H5T_NATIVE_INT64);
  auto captured = read_column<std::int64_t>(g, "captured_ns", H5T_NATIVE_INT64);
  for (const Status& status : {cycle.status(), stamp.status(), captured.status()}) {
    if (!status) return Status::error(where + status.message());
  }
  std::vector<std::vector<double>> columns;
  for (std::size_t i = 0; i < names->size(); ++i) {
    auto column = read_column<double>(g, dataset_name_for((*names)[i], i), H5T_NATIVE_DOUBLE);
    if (!column) return Status::error(where + column.error());
    columns.push_back(std::move(*column));
  }
  // A writer that died in the middle of a write may leave columns of different lengths:
  // keep the rows every column has.
  std::size_t rows = std::min({cycle->size(), stamp->size(), captured->size()});
  std::size_t longest = std::max({cycle->size(), stamp->size(), captured->size()});
  for (const auto& column : columns) {
    rows = std::min(rows, column.size());
    longest = std::max(longest, column.size());
  }
  if (rows != longest) {
    warnings.push_back(where + "columns have between " + std::to_string(rows) + " and " + std::to_string(longest) +
                       " rows (the writer stopped during a write); read the first " + std::to_string(rows));
  }
  // Rows the writer reserved but whose data never reached the file (a crash between the
  // extent's and the chunk's write, a full disk) read as the fill values: cycle UINT64_MAX,
  // stamps INT64_MIN. They end the readable part: what follows is not data.
  for (std::size_t row = 0; row < rows; ++row) {
    if ((*cycle)[row] == kMissingCycle || (*stamp)[row] == kMissingStamp) {
      warnings.push_back(where + "rows " + std::to_string(row) + " to " + std::to_string(rows - 1) +
                         " were reserved but never written (the writer stopped); read the first " +
                         std::to_string(row));
      rows = row;
      break;
    }
  }
  cycle->resize(rows);
  stamp->resize(rows);
  captured->resize(rows);
  data.cycle = std::move(*cycle);
  data.stamp_ns = std::move(*stamp);
  data.captured_ns = std::move(*captured);
  data.values.resize(rows * columns.size());
  for (std::size_t row = 0; row < rows; ++row) {
    for (std::size_t v = 0; v < columns.size(); ++v) data.values[row * columns.size() + v] = columns[v][row];
  }
  return data;
}

}  // namespace

Expected<Recording> read_recording(const std::string& path) {
  silence_hdf5_errors();
  const std::string where = "recording '" + path + "': ";
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  if (!file.valid()) return Status::error(where + "cannot open: " + hdf5_message());
  Recording recording;
  RootAttributes root{&recording, {}};
  if (H5Aiterate2(file.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_root_attribute, &root) < 0) {
    return Status::error(where + (root.error.empty() ? hdf5_message() : root.error));
  }
  const auto format = recording.text_attributes.find("format");
  if (format == recording.text_attributes.end() || format->second != kFormat) {
    return Status::error(where + "not a lodestone recording (root attribute format is not \"" + kFormat + "\")");
  }
  const auto version = recording.number_attributes.find("format_version");
  if (version == recording.number_attributes.end() || version->second > kFormatVersion) {
    return Status::error(where + "format_version is missing or newer than " + std::to_string(kFormatVersion) +
                         ": update lodestone to read it");
  }

  Handle signals(H5Gopen2(file.get(), "signals", H5P_DEFAULT));
  if (!signals.valid()) return Status::error(where + "group /signals is missing");
  std::vector<std::string> names;
  if (H5Literate(signals.get(), H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, collect_link_name, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);  // creation order not tracked (written by another tool): by name
    names.clear();
    if (H5Literate(signals.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_link_name, &names) < 0) {
      return Status::error(where + "cannot list /signals: " + hdf5_message());
    }
  }
  for (const auto& name : names) {
    auto series = read_series(signals.get(), name, recording.warnings);
    if (!series) return Status::error(where + series.error());
    recording.series.push_back(std::move(*series));
  }

  Handle events(H5Gopen2(file.get(), "events", H5P_DEFAULT));
  if (!events.valid()) return Status::error(where + "group /events is missing");
  auto cycle = read_column<std::uint64_t>(events.get(), "cycle", H5T_NATIVE_UINT64);
  auto stamp = read_column<std::int64_t>(events.get(), "stamp_ns", H5T_NATIVE_INT64);
  auto kind = read_string_column(events.get(), "kind");
  auto text = read_string_column(events.get(), "text");
  for (const Status& status : {cycle.status(), stamp.status(), kind.status(), text.status()}) {
    if (!status) return Status::error(where + "/events: " + status.message());
  }
  const std::size_t rows = std::min({cycle->size(), stamp->size(), kind->size(), text->size()});
  if (rows != std::max({cycle->size(), stamp->size(), kind->size(), text->size()})) {
    recording.warnings.push_back(
        "/events: columns differ in length (the writer stopped during a write); read the first " +
        std::to_string(rows));
  }
  for (std::size_t i = 0; i < rows; ++i) {
    if ((*cycle)[i] == kMissingCycle) {  // reserved, never written (see read_series)
      recording.warnings.push_back("/events: rows " + std::to_string(i) + " to " + std::to_string(rows - 1) +
                                   " were reserved but never written (the writer stopped); read the first " +
                                   std::to_string(i));
      break;
    }
    recording.events.push_back({(*cycle)[i], (*stamp)[i], std::move((*kind)[i]), std::move((*text)[i])});
  }
  return recording;
}

}  // namespace lode::record
