#include "replay.hpp"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <set>

#include "lode/sdk/plugin.hpp"
#include "lode/record/hdf5_recorder.hpp"

namespace lode::plugins {

namespace {

/// A relative `recording` is taken relative to the pipeline file's folder when the
/// configuration came from a file (its label is a path that exists), else to the
/// working directory (`lode replay` always writes absolute paths).
std::string resolve(const std::string& path, const SourceLocation& where) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (p.is_absolute() || where.file.empty()) return path;
  std::error_code ec;
  const fs::path config(where.file);
  if (fs::is_regular_file(config, ec)) return (config.parent_path() / p).lexically_normal().string();
  return path;
}

}  // namespace

Status ReplayBoard::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  const std::string given = params.text("recording");
  block_ = params.text("block", ctx.block_name());
  // The command input is optional and of any size, so `inputs: {command: ctrl.out}` of the
  // board this block replaces stays valid; it is never read.
  ctx.declare_input(command_, "command", {}, false);
  if (!params.ok()) return Status::error("invalid parameters");
  path_ = resolve(given, params.location("recording"));

  // Only the series played back are read: a board's raw inputs are a fraction of a recording
  // of every signal. The raw ones (what `lode replay` reads too, so the two share one copy);
  // another block's series, e.g. an estimator's output replayed as a measurement, by name.
  const std::string prefix = block_ + ".";
  const auto of_block = [&](const std::string& name) { return name.rfind(prefix, 0) == 0; };
  auto shared = record::read_recording_shared(path_, record::SeriesSelection::raw());
  if (shared && std::none_of((*shared)->series.begin(), (*shared)->series.end(),
                             [&](const auto& s) { return of_block(s.info.name); }))
    shared = record::read_recording_shared(path_, record::SeriesSelection::block(block_));
  if (!shared) {
    params.fail("recording", "cannot read recording '" + path_ + "': " + shared.error());
    return Status::error("invalid parameters");
  }
  recording_ = std::move(*shared);
  const record::Recording* rec = recording_.get();
  warnings_ = rec->warnings;
  std::set<std::string> recorded_blocks;
  std::size_t count = 0;
  const auto note_block = [&](const std::string& name) {
    const auto dot = name.find('.');
    if (dot != std::string::npos) recorded_blocks.insert(name.substr(0, dot));
  };
  for (const auto& name : rec->series_not_read) note_block(name);
  for (const auto& s : rec->series) {
    note_block(s.info.name);
    if (of_block(s.info.name)) ++count;
  }
  if (count == 0) {
    std::string known;
    for (const auto& b : recorded_blocks) known += (known.empty() ? "" : ", ") + b;
    params.fail(params.has("block") ? "block" : "recording",
                "recording '" + path_ + "' has no series of block '" + block_ + "' (blocks recorded: " +
                    (known.empty() ? std::string("none") : known) + ")");
    return Status::error("invalid parameters");
  }

  // Streams first, ports after: declare_output keeps a reference to each port, so the
  // vector must not move once they are declared.
  streams_.clear();
  streams_.reserve(count);
  for (const auto& s : rec->series) {
    if (!of_block(s.info.name)) continue;
    Stream st;
    st.port = s.info.name.substr(prefix.size());
    st.kind = s.info.kind;
    st.width = s.width();
    for (std::size_t i = 0; i < s.info.names.size(); ++i)
      st.elements.push_back({s.info.names[i], i < s.info.units.size() ? s.info.units[i] : ""});
    st.rows = s.rows();
    st.cycle = s.cycle.data();
    st.values = s.values.data();
    streams_.push_back(std::move(st));
  }

  // Every series must hold the same cycles. A recording may skip cycle numbers: the periods its
  // real-time loop skipped after an overrun (`overrun_policy: skip`), which no block ran. What
  // the recorder itself failed to keep (its `dropped_cycles`) did run: a replay cannot invent
  // those samples, so a gap is refused then.
  const Stream& first = streams_.front();
  rows_ = first.rows;
  first_cycle_ = rows_ > 0 ? first.cycle[0] : 0;
  const auto dropped = rec->number_attributes.find("dropped_cycles");
  const bool recorder_lost_cycles = dropped != rec->number_attributes.end() && dropped->second > 0;
  bool ok = true;
  if (rows_ == 0) {
    params.fail("recording", "series '" + prefix + first.port + "' in '" + path_ + "' has no samples");
    ok = false;
  }
  for (std::size_t k = 1; ok && k < rows_; ++k) {
    if (first.cycle[k] <= first.cycle[k - 1]) {
      params.fail("recording", "series '" + prefix + first.port + "' in '" + path_ + "': row " + std::to_string(k) +
                                   " is cycle " + std::to_string(first.cycle[k]) + ", not after cycle " +
                                   std::to_string(first.cycle[k - 1]) + " (a damaged recording?)");
      ok = false;
    } else if (first.cycle[k] != first.cycle[k - 1] + 1 && recorder_lost_cycles) {
      params.fail("recording", "series '" + prefix + first.port + "' in '" + path_ + "' has a gap: row " +
                                   std::to_string(k) + " is cycle " + std::to_string(first.cycle[k]) + ", expected " +
                                   std::to_string(first.cycle[k - 1] + 1) + " (the recorder lost " +
                                   std::to_string(static_cast<std::uint64_t>(dropped->second)) +
                                   " cycles: their samples are not in the file)");
      ok = false;
    } else if (first.cycle[k] != first.cycle[k - 1] + 1) {
      skipped_cycles_ += first.cycle[k] - first.cycle[k - 1] - 1;
    }
  }
  for (const auto& st : streams_) {
    if (!ok || &st == &first) continue;
    const std::string name = prefix + st.port;
    // A cycle one series has and another has not: the recorder dropped it from one (checked
    // first: it is the cause when the lengths differ too).
    const std::size_t common = std::min(st.rows, rows_);
    const std::size_t at = static_cast<std::size_t>(std::mismatch(st.cycle, st.cycle + common, first.cycle).first - st.cycle);
    if (at < common) {
      const bool missing_here = st.cycle[at] > first.cycle[at];
      const Stream& other = missing_here ? first : st;
      params.fail("recording", "series '" + (missing_here ? name : prefix + first.port) + "' in '" + path_ +
                                   "' has a gap: row " + std::to_string(at) + " is cycle " +
                                   std::to_string(missing_here ? st.cycle[at] : first.cycle[at]) + ", expected " +
                                   std::to_string(other.cycle[at]) + " (as in '" + prefix + other.port +
                                   "': cycles were dropped while recording)");
      ok = false;
    } else if (st.rows != rows_) {
      params.fail("recording", "series '" + name + "' in '" + path_ + "' has " + std::to_string(st.rows) +
                                   " samples, '" + prefix + first.port + "' has " + std::to_string(rows_));
      ok = false;
    }
  }
  for (auto& st : streams_) ctx.declare_output(st.out, st.port, st.elements);
  return ok ? Status::ok() : Status::error("invalid recording");
}

Status ReplayBoard::activate() {
  // Outputs are valid before the first cycle (as io.sim's are): the first recorded row.
  if (rows_ > 0) copy_row(0);
  return Status::ok();
}

void ReplayBoard::copy_row(std::size_t row) noexcept {
  for (auto& st : streams_)
    std::memcpy(st.out.data(), st.values + row * st.width, st.width * sizeof(double));
}

StepStatus ReplayBoard::step(const Tick& tick) noexcept {
  // The row of this cycle: the one after the last in a run that goes forward (every cycle, or
  // the recorded ones), else found by bisection.
  const std::uint64_t* cycles = streams_.front().cycle;
  std::size_t row = next_row_;
  if (row >= rows_ || cycles[row] != tick.cycle)
    row = static_cast<std::size_t>(std::lower_bound(cycles, cycles + rows_, tick.cycle) - cycles);
  if (row >= rows_) return fault("end of recording");
  if (tick.cycle < first_cycle_) return fault("recording has no sample for this cycle (it starts later)");
  if (cycles[row] != tick.cycle)
    return fault("the recording has no sample for this cycle: its real-time loop skipped it after an overrun "
                 "(`lode replay` runs the recorded cycles only)");
  copy_row(row);
  next_row_ = row + 1;
  return StepStatus::ok;
}

void ReplayBoard::describe(Json& out) const {
  out["recording"] = path_;
  out["block"] = block_;
  out["rows"] = static_cast<std::uint64_t>(rows_);
  out["first_cycle"] = first_cycle_;
  out["skipped_cycles"] = skipped_cycles_;
  Json series = Json::array();
  for (const auto& st : streams_) {
    Json s = Json::object();
    s["port"] = st.port;
    s["kind"] = st.kind;
    s["width"] = static_cast<std::uint64_t>(st.width);
    series.push(std::move(s));
  }
  out["series"] = std::move(series);
  if (!warnings_.empty()) {
    Json w = Json::array();
    for (const auto& text : warnings_) w.push(text);
    out["warnings"] = std::move(w);
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"recording", "text", nullptr,
     "HDF5 file written by `lode run --record` (relative: to the pipeline file's folder)"},
    {"block", "text", "this block's name", "the recorded block whose outputs are played back (e.g. stage)"},
};

constexpr PortSpec kPorts[] = {
    {"command", PortDirection::in, "optional, any size: accepted and ignored (the original board's wiring stays valid)"},
    {"<port>", PortDirection::out, "one per recorded series <block>.<port>, with its recorded element names and units"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::ReplayBoard, "io.replay", lode::PluginKind::io, "0.1.0",
            "Replays a recorded board's outputs (lode run --record) cycle by cycle, bit for bit",
            lode::plugins::kParams, lode::plugins::kPorts)
