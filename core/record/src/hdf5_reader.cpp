// Reading a recording back (lode replay, tests): every series with its elements, units and
// time columns, the events and the attributes; what cannot be read is said, not guessed.
#include "lode/record/hdf5_recorder.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <mutex>

#include "hdf5_common.hpp"
#include "lode/host_memory.hpp"
#include "read_in_child.hpp"

namespace lode::record {

using namespace detail;

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

/// The attributes of series group `g` into `data` (its info and counters).
Status read_series_attributes(hid_t g, SeriesData& data) {
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
    if (!status) return status;
  }
  if (names->size() != units->size()) return Status::error("attributes names and units differ in length");
  data.info.topic = *topic;
  data.info.kind = *kind;
  data.info.names = *names;
  data.info.units = *units;
  data.info.rate_hz = *rate;
  data.info.pipeline_rate_hz = *pipeline_rate;
  data.info.decimation = *decimation;
  data.gaps = *gaps;
  data.out_of_order = *out_of_order;
  return {};
}

Expected<SeriesData> read_series(hid_t signals, const std::string& name, std::vector<std::string>& warnings) {
  const std::string where = "/signals/" + name + ": ";
  Handle group(H5Gopen2(signals, name.c_str(), H5P_DEFAULT));
  if (!group.valid()) return Status::error(where + "not a group: " + hdf5_message());
  const hid_t g = group.get();
  SeriesData data;
  data.info.name = name;
  if (Status attributes = read_series_attributes(g, data); !attributes)
    return Status::error(where + attributes.message());
  const std::vector<std::string>* names = &data.info.names;

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

/// What read_column() goes through to read dataset `name` of `group`, without reading all of
/// it: the first row of every chunk (so HDF5 walks the whole chunk index, finds every chunk
/// and decodes it: a filtered chunk is decoded whole), converted to `memory_type` as
/// read_column() converts it. The other rows of an unfiltered chunk are plain bytes next to
/// the one read: nothing in them can make the library misbehave. A dataset that is not
/// chunked (written by another tool) is read whole, a slab at a time into one small buffer.
Status read_column_through(hid_t group, const std::string& name, hid_t memory_type) {
  // No chunk cache: an unfiltered chunk's one row is read from the file as it is, instead of
  // the whole chunk into a zeroed buffer first.
  Handle access(H5Pcreate(H5P_DATASET_ACCESS));
  H5Pset_chunk_cache(access.get(), 0, 0, H5D_CHUNK_CACHE_W0_DEFAULT);
  Handle dataset(H5Dopen2(group, name.c_str(), access.get()));
  if (!dataset.valid()) return Status::error("dataset '" + name + "' is missing");
  Handle space(H5Dget_space(dataset.get()));
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count < 0 || H5Sget_simple_extent_ndims(space.get()) != 1)
    return Status::error("dataset '" + name + "': not a column: " + hdf5_message());
  if (count == 0) return {};
  const auto rows = static_cast<hsize_t>(count);
  Handle create(H5Dget_create_plist(dataset.get()));
  hsize_t chunk_rows = 0;
  if (!create.valid() || H5Pget_layout(create.get()) != H5D_CHUNKED || H5Pget_chunk(create.get(), 1, &chunk_rows) != 1 ||
      chunk_rows == 0) {
    chunk_rows = 1;  // every row: read whole
  }
  const hsize_t chunks = (rows + chunk_rows - 1) / chunk_rows;
  constexpr hsize_t kSlabRows = 16384;  // rows (one from each chunk) per read
  std::vector<std::uint64_t> slab(static_cast<std::size_t>(std::min(chunks, kSlabRows)));
  for (hsize_t first_chunk = 0; first_chunk < chunks; first_chunk += kSlabRows) {
    const hsize_t start = first_chunk * chunk_rows, stride = chunk_rows;
    const hsize_t picked = std::min(kSlabRows, chunks - first_chunk);
    Handle memory_space(H5Screate_simple(1, &picked, nullptr));
    if (H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, &start, &stride, &picked, nullptr) < 0 ||
        H5Dread(dataset.get(), memory_type, memory_space.get(), space.get(), H5P_DEFAULT, slab.data()) < 0) {
      return Status::error("dataset '" + name + "': " + hdf5_message());
    }
  }
  return {};
}

/// Everything read_series() reads of series `name`, read and dropped (read_column_through);
/// the first error, worded as read_series() words it.
Status read_series_through(hid_t signals, const std::string& name) {
  const std::string where = "/signals/" + name + ": ";
  Handle group(H5Gopen2(signals, name.c_str(), H5P_DEFAULT));
  if (!group.valid()) return Status::error(where + "not a group: " + hdf5_message());
  SeriesData data;
  if (Status attributes = read_series_attributes(group.get(), data); !attributes)
    return Status::error(where + attributes.message());
  std::vector<std::pair<std::string, hid_t>> columns = {
      {"cycle", H5T_NATIVE_UINT64}, {"stamp_ns", H5T_NATIVE_INT64}, {"captured_ns", H5T_NATIVE_INT64}};
  for (std::size_t i = 0; i < data.info.names.size(); ++i)
    columns.emplace_back(dataset_name_for(data.info.names[i], i), H5T_NATIVE_DOUBLE);
  for (const auto& [column, memory_type] : columns)
    if (Status read = read_column_through(group.get(), column, memory_type); !read)
      return Status::error(where + read.message());
  return {};
}

/// The memory read_series() takes for the series `names` of /signals: the rows of each
/// (its cycle column's length) times its cycle, stamp and captured columns and its values,
/// held until the end, plus the largest series' values once more (its columns, read before
/// they are interleaved). Series it cannot size count for nothing: read_series() reports them.
ReadCost memory_to_read(hid_t signals, const std::vector<std::string>& names) {
  ReadCost cost;
  std::uint64_t largest_values = 0;
  for (const auto& name : names) {
    Handle group(H5Gopen2(signals, name.c_str(), H5P_DEFAULT));
    if (!group.valid()) continue;
    Handle cycle(H5Dopen2(group.get(), "cycle", H5P_DEFAULT));
    auto elements = read_string_attribute(group.get(), "names");
    if (!cycle.valid() || !elements) continue;
    Handle space(H5Dget_space(cycle.get()));
    const hssize_t rows = space.valid() ? H5Sget_simple_extent_npoints(space.get()) : -1;
    if (rows <= 0) continue;
    const std::uint64_t values = static_cast<std::uint64_t>(rows) * elements->size() * sizeof(double);
    const std::uint64_t held = static_cast<std::uint64_t>(rows) * 3 * sizeof(std::uint64_t) + values;
    cost.bytes += held;
    cost.largest_series = std::max(cost.largest_series, held + values);
    cost.rows = std::max(cost.rows, static_cast<std::uint64_t>(rows));
    largest_values = std::max(largest_values, values);
  }
  H5Eclear2(H5E_DEFAULT);
  cost.bytes += largest_values;
  return cost;
}

/// Refuses, with the figures, reading `what` of the recording `where` names when it takes more
/// memory than this process has left: before the reading fills the memory and the OOM killer
/// ends this process (or another).
Status fits_in_memory(const std::string& where, const std::string& what, std::uint64_t needed) {
  const auto available = available_memory_bytes();
  if (!available || needed <= *available) return Status::ok();
  return Status::error(where + "reading " + what + " takes about " + format_bytes(needed) +
                       " of memory and this process has " + format_bytes(*available) +
                       " left (available memory, within its control group's limit); read it on a machine "
                       "with more memory free");
}

/// The `kind` attribute of series `name` ("" when it cannot be read: read_series says why).
std::string series_kind(hid_t signals, const std::string& name) {
  Handle group(H5Gopen2(signals, name.c_str(), H5P_DEFAULT));
  auto kind = group.valid() ? read_text_attribute(group.get(), "kind") : Expected<std::string>(Status::error(""));
  H5Eclear2(H5E_DEFAULT);
  return kind ? *kind : std::string();
}

}  // namespace

SeriesSelection SeriesSelection::all() {
  return {"all", [](const std::string&, const std::string&) { return true; }};
}

SeriesSelection SeriesSelection::raw() {
  return {"raw", [](const std::string&, const std::string& kind) { return kind == "raw"; }};
}

SeriesSelection SeriesSelection::block(const std::string& block) {
  return {"block " + block,
          [prefix = block + "."](const std::string& name, const std::string&) { return name.rfind(prefix, 0) == 0; }};
}

SeriesSelection SeriesSelection::one(const std::string& series) {
  return {"series " + series, [series](const std::string& name, const std::string&) { return name == series; }};
}

Expected<Recording> read_recording(const std::string& path) { return read_recording(path, SeriesSelection::all()); }

namespace {

/// A recording open for reading: its root attributes checked, /signals open and listed.
struct OpenRecording {
  Handle file, signals;
  std::vector<std::string> names;  ///< of /signals, in the order they were added
};

Status read_whole_file(const std::string& path);

/// What a user gets wrong most often, said in their words before HDF5 says it in its own
/// ("unable to open file: file signature not found"): no such file, not a file, not readable,
/// not HDF5 at all (a configuration given where the recording goes).
Status check_is_hdf5_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    return Status::error(errno == ENOENT ? std::string("no such file") : std::string(std::strerror(errno)));
  if (S_ISDIR(st.st_mode)) return Status::error("a directory, not a recording");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::error(std::string("cannot be read: ") + std::strerror(errno));
  // The HDF5 signature, at offset 0 or after a user block (512, 1024, 2048, ... bytes).
  static constexpr char kSignature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  char head[8];
  for (std::uint64_t offset = 0; offset == 0 || offset < static_cast<std::uint64_t>(st.st_size); offset = offset ? 2 * offset : 512) {
    in.clear();
    in.seekg(static_cast<std::streamoff>(offset));
    if (!in.read(head, sizeof head)) break;
    if (std::memcmp(head, kSignature, sizeof head) == 0) return Status::ok();
  }
  return Status::error(st.st_size == 0 ? std::string("an empty file, not a recording")
                                       : std::string("not an HDF5 file: a recording is what `lode run --record`, "
                                                     "`lode record` or `lode replay` writes"));
}

Expected<OpenRecording> open_recording(const std::string& path, Recording& attributes) {
  silence_hdf5_errors();
  const std::string where = "recording '" + path + "': ";
  if (Status usable = check_is_hdf5_file(path); !usable) return Status::error(where + usable.message());
  if (Status checked = read_first_in_child(path, read_whole_file); !checked)
    return Status::error(where + checked.message());
  OpenRecording open;
  open.file = Handle(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  if (!open.file.valid()) return Status::error(where + "cannot open: " + hdf5_message());
  RootAttributes root{&attributes, {}};
  if (H5Aiterate2(open.file.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_root_attribute, &root) < 0) {
    return Status::error(where + (root.error.empty() ? hdf5_message() : root.error));
  }
  const auto format = attributes.text_attributes.find("format");
  if (format == attributes.text_attributes.end() || format->second != kFormat) {
    return Status::error(where + "not a lodestone recording (root attribute format is not \"" + kFormat + "\")");
  }
  const auto version = attributes.number_attributes.find("format_version");
  if (version == attributes.number_attributes.end() || version->second > kFormatVersion) {
    return Status::error(where + "format_version is missing or newer than " + std::to_string(kFormatVersion) +
                         ": update lodestone to read it");
  }
  open.signals = Handle(H5Gopen2(open.file.get(), "signals", H5P_DEFAULT));
  if (!open.signals.valid()) return Status::error(where + "group /signals is missing");
  if (H5Literate(open.signals.get(), H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, collect_link_name, &open.names) < 0) {
    H5Eclear2(H5E_DEFAULT);  // creation order not tracked (written by another tool): by name
    open.names.clear();
    if (H5Literate(open.signals.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_link_name, &open.names) < 0) {
      return Status::error(where + "cannot list /signals: " + hdf5_message());
    }
  }
  return open;
}

/// /events into `recording` (rows never written are left out, with a warning).
Status read_events(hid_t file, Recording& recording) {
  Handle events(H5Gopen2(file, "events", H5P_DEFAULT));
  if (!events.valid()) return Status::error("group /events is missing");
  auto cycle = read_column<std::uint64_t>(events.get(), "cycle", H5T_NATIVE_UINT64);
  auto stamp = read_column<std::int64_t>(events.get(), "stamp_ns", H5T_NATIVE_INT64);
  auto kind = read_string_column(events.get(), "kind");
  auto text = read_string_column(events.get(), "text");
  for (const Status& status : {cycle.status(), stamp.status(), kind.status(), text.status()}) {
    if (!status) return Status::error("/events: " + status.message());
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
  return {};
}

/// Every part of the file that read_recording(), read_cost() and SeriesReader may touch, read
/// and dropped: what read_first_in_child() runs in its child. The first error, as a reader
/// would report it after "recording '<path>': ".
Status read_whole_file(const std::string& path) {
  Recording recording;
  auto opened = open_recording(path, recording);
  if (!opened) {
    const std::string prefix = "recording '" + path + "': ";
    const std::string& message = opened.error();
    return Status::error(message.rfind(prefix, 0) == 0 ? message.substr(prefix.size()) : message);
  }
  note_progress();
  (void)memory_to_read(opened->signals.get(), opened->names);
  for (const auto& name : opened->names) {
    (void)series_kind(opened->signals.get(), name);
    if (Status series = read_series_through(opened->signals.get(), name); !series) return series;
    note_progress();
  }
  return read_events(opened->file.get(), recording);
}

}  // namespace

struct SeriesReader::Impl {
  std::string path;
  OpenRecording open;
};

Expected<std::unique_ptr<SeriesReader>> SeriesReader::open(const std::string& path) {
  Recording attributes;
  auto opened = open_recording(path, attributes);
  if (!opened) return opened.status();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->open = std::move(*opened);
  return std::unique_ptr<SeriesReader>(new SeriesReader(std::move(impl)));
}

SeriesReader::SeriesReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SeriesReader::~SeriesReader() = default;

const std::vector<std::string>& SeriesReader::names() const { return impl_->open.names; }

Expected<SeriesData> SeriesReader::read(const std::string& name, std::vector<std::string>& warnings) {
  const std::string where = "recording '" + impl_->path + "': ";
  if (Status s = fits_in_memory(where, "series " + name, memory_to_read(impl_->open.signals.get(), {name}).bytes); !s)
    return s;
  auto series = read_series(impl_->open.signals.get(), name, warnings);
  if (!series) return Status::error(where + series.error());
  return series;
}

Expected<ReadCost> read_cost(const std::string& path, const SeriesSelection& selection) {
  Recording attributes;
  auto opened = open_recording(path, attributes);
  if (!opened) return opened.status();
  std::erase_if(opened->names,
                [&](const std::string& name) { return !selection.wanted(name, series_kind(opened->signals.get(), name)); });
  return memory_to_read(opened->signals.get(), opened->names);
}

Expected<Recording> read_recording(const std::string& path, const SeriesSelection& selection) {
  const std::string where = "recording '" + path + "': ";
  Recording recording;
  auto opened = open_recording(path, recording);
  if (!opened) return opened.status();
  Handle file = std::move(opened->file);
  Handle signals = std::move(opened->signals);
  std::vector<std::string> names = std::move(opened->names);
  std::vector<std::string> wanted;
  for (auto& name : names) {
    if (selection.wanted(name, series_kind(signals.get(), name)))
      wanted.push_back(std::move(name));
    else
      recording.series_not_read.push_back(std::move(name));
  }
  names = std::move(wanted);
  // What is read is read whole: too large for the memory left, it is refused with the figures.
  if (Status s = fits_in_memory(where, "its " + std::to_string(names.size()) + " series",
                                memory_to_read(signals.get(), names).bytes);
      !s)
    return s;
  for (const auto& name : names) {
    auto series = read_series(signals.get(), name, recording.warnings);
    if (!series) return Status::error(where + series.error());
    recording.series.push_back(std::move(*series));
  }

  if (Status events = read_events(file.get(), recording); !events) return Status::error(where + events.message());
  return recording;
}

}  // namespace lode::record

namespace lode::record {

Expected<std::shared_ptr<const Recording>> read_recording_shared(const std::string& path) {
  return read_recording_shared(path, SeriesSelection::all());
}

Expected<std::shared_ptr<const Recording>> read_recording_shared(const std::string& path,
                                                                 const SeriesSelection& selection) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    auto r = read_recording(path, selection);  // says why it cannot be read
    if (!r) return r.status();
    return std::shared_ptr<const Recording>(std::make_shared<Recording>(std::move(*r)));
  }
  // The file's identity and version: a file rewritten in between is read again.
  const std::string key = file_identity(st) + ":" + selection.key;
  static std::mutex mutex;
  static std::map<std::string, std::weak_ptr<const Recording>> held;
  std::lock_guard lock(mutex);
  if (auto it = held.find(key); it != held.end()) {
    if (auto shared = it->second.lock()) return shared;
  }
  auto r = read_recording(path, selection);
  if (!r) return r.status();
  std::shared_ptr<const Recording> shared = std::make_shared<Recording>(std::move(*r));
  std::erase_if(held, [](const auto& entry) { return entry.second.expired(); });
  held[key] = shared;
  return shared;
}

}  // namespace lode::record
