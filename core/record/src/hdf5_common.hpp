// Internal to the HDF5 recording: the format's constants and the HDF5 plumbing the writer
// (hdf5_recorder.cpp) and the reader (hdf5_reader.cpp) share.
#pragma once

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <ctime>
#include <limits>
#include <set>
#include <utility>
#include <string>
#include <vector>

#include "lode/record/hdf5_recorder.hpp"

namespace lode::record::detail {

inline constexpr const char* kFormat = "lodestone-recording";
inline constexpr int kFormatVersion = 1;
inline constexpr hsize_t kMaxChunkRows = 4096;
inline constexpr hsize_t kMinChunkRows = 64;
inline constexpr hsize_t kEventChunkRows = 256;
/// Chunk of a recording whose length is known in advance (Recorder::expect_rows): 8192 rows
/// = 64 KiB per column. The chunks are written whole, as they are (write_whole_chunk()),
/// beside the cycles (a simulated run's recording thread), and the last one when the file is
/// closed, after the last cycle. Measured on a 30 s replay (24 000 rows, 100 columns): writing
/// 19 MB to ext4 in 16 KiB pieces took the kernel about twice as long as in 64 KiB ones, and
/// the recording thread, at 2048 rows, about as much CPU time as the cycles beside it; at
/// 16384 rows it fell behind at each chunk boundary, with the same last chunk (7616 rows).
inline constexpr hsize_t kKnownLengthChunkRows = 8192;
inline constexpr std::array<const char*, 4> kTimeColumns = {"cycle", "stamp_ns", "captured_ns", "time_s"};

// ---- HDF5 plumbing ------------------------------------------------------------------------

// HDF5 prints its error stack to stderr by default; errors become Status messages instead.
// The setting is per thread in the thread-safe build, so every entry point calls this.
//
// The first call also tells HDF5 not to install its atexit() clean-up, before anything else
// initialises the library. Every file this code opens it closes itself; the clean-up only
// ever matters for objects HDF5 could not close, and with those it crashes: after a write
// failed (a full disk) the datasets stay open, and closing them at exit dies of SIGSEGV in
// H5D_close, taking the run's exit status and summary with it.
inline void silence_hdf5_errors() {
  static const bool no_atexit = [] { return H5dont_atexit() >= 0; }();
  (void)no_atexit;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

inline herr_t collect_error(unsigned /*depth*/, const H5E_error2_t* error, void* data) {
  auto* descriptions = static_cast<std::vector<std::string>*>(data);
  if (error->desc != nullptr && *error->desc != '\0' &&
      (descriptions->empty() || descriptions->back() != error->desc)) {
    descriptions->emplace_back(error->desc);
  }
  return 0;
}

/// The failed call's HDF5 error stack as "outermost: innermost" (the middle entries repeat
/// "unable to open file"), on one line, then cleared.
inline std::string hdf5_message() {
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

inline Handle utf8_string_type() {
  Handle type(H5Tcopy(H5T_C_S1));
  H5Tset_size(type.get(), H5T_VARIABLE);
  H5Tset_cset(type.get(), H5T_CSET_UTF8);
  return type;
}

// Link and attribute names are flagged UTF-8 so "θ" reads back as "θ" in Python and MATLAB.
inline Handle utf8_link_properties() {
  Handle properties(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_char_encoding(properties.get(), H5T_CSET_UTF8);
  return properties;
}

inline Handle utf8_attribute_properties() {
  Handle properties(H5Pcreate(H5P_ATTRIBUTE_CREATE));
  H5Pset_char_encoding(properties.get(), H5T_CSET_UTF8);
  return properties;
}

/// Opens attribute `key` of `object` for writing with `file_type` and `space`, replacing an
/// attribute of the same name (set_attribute twice keeps the last value).
inline Handle fresh_attribute(hid_t object, const std::string& key, hid_t file_type, hid_t space) {
  if (H5Aexists(object, key.c_str()) > 0) H5Adelete(object, key.c_str());
  Handle acpl = utf8_attribute_properties();
  return Handle(H5Acreate2(object, key.c_str(), file_type, space, acpl.get(), H5P_DEFAULT));
}

inline Status write_text_attribute(hid_t object, const std::string& key, const std::string& value) {
  Handle type = utf8_string_type();
  Handle space(H5Screate(H5S_SCALAR));
  Handle attribute = fresh_attribute(object, key, type.get(), space.get());
  const char* text = value.c_str();
  if (!attribute.valid() || H5Awrite(attribute.get(), type.get(), &text) < 0) {
    return Status::error("attribute '" + key + "': " + hdf5_message());
  }
  return {};
}

inline Status write_text_array_attribute(hid_t object, const std::string& key, const std::vector<std::string>& values) {
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

inline Status write_number_attribute(hid_t object, const std::string& key, hid_t file_type, hid_t memory_type,
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
inline Status update_counter_attribute(hid_t object, const char* key, std::uint64_t value) {
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

/// A 1-D dataset of `initial_rows` rows that grows without limit, chunked by `chunk_rows`;
/// `fill` (of `fill_type`, in memory) is what unwritten rows read as (nullptr: HDF5's
/// default). Without a chunk cache (`cache` false) a whole-chunk write goes straight to the
/// file instead of being copied into the cache and flushed at close.
inline Handle create_column(hid_t group, const std::string& name, hid_t file_type, hsize_t chunk_rows,
                            hid_t fill_type = -1, const void* fill = nullptr, hsize_t initial_rows = 0,
                            bool cache = true) {
  const hsize_t unlimited = H5S_UNLIMITED;
  Handle space(H5Screate_simple(1, &initial_rows, &unlimited));
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
  H5Pset_chunk(dcpl.get(), 1, &chunk_rows);
  if (fill != nullptr) H5Pset_fill_value(dcpl.get(), fill_type, fill);
  Handle lcpl = utf8_link_properties();
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS));
  if (!cache) {
    H5Pset_chunk_cache(dapl.get(), 0, 0, H5D_CHUNK_CACHE_W0_DEFAULT);
  } else {
    // Rows are only appended: a chunk once filled is never touched again, so the cache needs
    // room for the chunk being filled and the one before it, not HDF5's default 1 MiB per
    // dataset (about 90 MiB for a pipeline's hundred columns, held for nothing). w0 = 1:
    // evict fully written chunks first.
    const std::size_t chunk_bytes = static_cast<std::size_t>(chunk_rows) * H5Tget_size(file_type);
    H5Pset_chunk_cache(dapl.get(), 11, 2 * chunk_bytes, 1.0);
  }
  return Handle(H5Dcreate2(group, name.c_str(), file_type, space.get(), lcpl.get(), dcpl.get(), dapl.get()));
}

/// Writes `count` rows from `data` at row `old_rows` of `dataset`, first extending it when
/// its `extent` is shorter (a dataset created at its final size is never extended).
inline bool append_to_column(hid_t dataset, hsize_t old_rows, hsize_t count, hid_t memory_type, const void* data,
                             hsize_t extent, hid_t transfer = H5P_DEFAULT) {
  const hsize_t new_rows = old_rows + count;
  if (new_rows > extent && H5Dset_extent(dataset, &new_rows) < 0) return false;
  Handle file_space(H5Dget_space(dataset));
  if (!file_space.valid() ||
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, &old_rows, nullptr, &count, nullptr) < 0) {
    return false;
  }
  Handle memory_space(H5Screate_simple(1, &count, nullptr));
  return H5Dwrite(dataset, memory_type, memory_space.get(), file_space.get(), transfer, data) >= 0;
}

/// Writes the chunk that starts at row `first_row` of `dataset` from `data`, which holds a
/// whole chunk of `chunk_rows` 8-byte elements laid out as the file stores them (its
/// little-endian types on a little-endian host), `count` of them rows of the dataset (any
/// others past its `extent`, never read): the dataset first extended to first_row + count
/// where it is shorter. H5Dwrite_chunk hands the bytes to the file as they are; H5Dwrite would
/// first allocate and zero a chunk buffer, work out the selection and copy the rows into it.
inline bool write_whole_chunk(hid_t dataset, hsize_t first_row, hsize_t count, hsize_t chunk_rows, const void* data,
                              hsize_t extent) {
  const hsize_t new_rows = first_row + count;
  if (new_rows > extent && H5Dset_extent(dataset, &new_rows) < 0) return false;
  return H5Dwrite_chunk(dataset, H5P_DEFAULT, 0, &first_row, static_cast<std::size_t>(chunk_rows) * 8, data) >= 0;
}

inline std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> text{};
  std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text.data();
}

inline bool valid_link_name(const std::string& name) {
  return !name.empty() && name != "." && name.find('/') == std::string::npos;
}

inline hsize_t chunk_rows_for(double rate_hz) {
  hsize_t rows = kMaxChunkRows;
  if (rate_hz > 0 && std::isfinite(rate_hz)) {
    rows = std::min<hsize_t>(kMaxChunkRows, static_cast<hsize_t>(std::ceil(rate_hz)));  // 1 s
  }
  return std::max(rows, kMinChunkRows);
}

}  // namespace lode::record::detail
