#include "run_recording.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "lode/sdk/plugin.hpp"
#include "run_timing.hpp"

namespace lode::cli {

RunRecorder::RunRecorder(const Pipeline& pipeline, Scheduler& scheduler, EventLog& events,
                         const OutputDigest& digest)
    : pipeline_(pipeline), scheduler_(scheduler), events_(events), stats_(scheduler.stats()), digest_(digest),
      tap_(pipeline.signals()) {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  hostname_ = host;
  const Json d = pipeline_.describe();
  Json plugins = Json::object();
  Json blocks = Json::object();
  if (const Json* bj = d.find("blocks")) {
    for (const auto& [name, b] : bj->members()) {
      const Json* plugin = b.find("plugin");
      const Json* file = b.find("plugin_file");
      const Json* kind = b.find("kind");
      if (!plugin) continue;
      blocks[name] = plugin->as_string();
      if (file) plugins[plugin->as_string()] = file->as_string();
      if (kind && kind->as_string() == to_string(PluginKind::io)) io_blocks_.push_back(name);
    }
  }
  plugins_json_ = plugins.dump(-1);
  blocks_json_ = blocks.dump(-1);
}

Status RunRecorder::open(const std::string& path, std::uint64_t expected_cycles) {
  std::lock_guard lock(mutex_);
  return open_locked(path, expected_cycles);
}

RunRecorder::~RunRecorder() { stop_writer(); }

void RunRecorder::on_idle() {
  if (writer_.joinable()) {
    auto& tap = tap_.tap();
    if (tap.queued() * 2 <= tap.capacity()) {
      // No mutex here: the writer may hold it for a whole chunk's write. A wake that comes
      // just before it waits is lost and it wakes at the end of its pause instead.
      writer_pending_.store(true, std::memory_order_release);
      writer_wake_.notify_one();
      return;
    }
  }
  std::lock_guard lock(mutex_);
  drain_locked();
  flush_locked(false);
}

void RunRecorder::start_writer() {
  if (writer_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    writer_stop_ = false;
  }
  writer_ = std::thread([this] { write_until_stopped(); });
}

void RunRecorder::stop_writer() {
  if (!writer_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    writer_stop_ = true;
  }
  writer_wake_.notify_one();
  writer_.join();
}

void RunRecorder::write_until_stopped() {
  // The pause only bounds a lost wake: on_idle() wakes the writer every 1024 cycles.
  constexpr auto kPause = std::chrono::milliseconds(5);
  std::unique_lock lock(mutex_);
  while (!writer_stop_) {
    writer_wake_.wait_for(lock, kPause, [this] { return writer_stop_ || writer_pending_.load(std::memory_order_acquire); });
    writer_pending_.store(false, std::memory_order_relaxed);
    if (writer_held_.load()) continue;
    drain_locked();
    flush_locked(false);
  }
}

Status RunRecorder::close() {
  stop_writer();
  std::lock_guard lock(mutex_);
  return recorder_ ? close_locked() : Status{};
}

Json RunRecorder::finished() const {
  std::lock_guard lock(mutex_);
  return finished_;
}

Status RunRecorder::open_locked(const std::string& path, std::uint64_t expected_cycles) {
  if (recorder_) return Status::error("already recording to " + path_ + " (record_stop first)");
  auto r = record::Recorder::create(path, source_);
  if (!r) return Status::error(r.error());
  recorder_ = std::move(*r);
  if (expected_cycles > 0) recorder_->expect_rows(expected_cycles);
  recorder_->set_attribute("pipeline", pipeline_.name());
  recorder_->set_attribute("config_file", pipeline_.source_file());
  recorder_->set_attribute("config", pipeline_.source_text());
  recorder_->set_attribute("host", hostname_);
  recorder_->set_attribute("rate_hz", pipeline_.rate_hz());
  // The exact resolved configuration is the YAML text above plus the plugin files.
  recorder_->set_attribute("lode_plugins", plugins_json_);
  recorder_->set_attribute("lode_blocks", blocks_json_);
  series_.clear();
  for (const auto& s : tap_.tap().signals()) {
    record::SeriesInfo info;
    info.name = s.name();
    const bool raw = std::find(io_blocks_.begin(), io_blocks_.end(), s.block) != io_blocks_.end();
    info.kind = raw ? "raw" : "signal";
    for (const auto& e : *s.elements) {
      info.names.push_back(e.name);
      info.units.push_back(e.unit);
    }
    info.rate_hz = pipeline_.rate_hz();
    info.pipeline_rate_hz = pipeline_.rate_hz();
    auto id = recorder_->add_series(info);
    if (!id) {
      recorder_.reset();
      return Status::error(id.error());
    }
    series_.push_back(*id);
  }
  // Stale records from an earlier recording are dropped before the gate opens.
  rows_.clear();
  tap_.tap().drain(rows_);
  rows_.clear();
  path_ = path;
  recorded_cycles_ = 0;
  flushed_cycles_ = 0;
  last_flush_ = std::chrono::steady_clock::now();
  first_cycle_.reset();
  from_start_ = !running_.load();
  event_cursor_ = 0;
  tap_.open().store(true, std::memory_order_release);
  return {};
}

void RunRecorder::drain_locked() {
  if (!recorder_) return;
  // A batch at a time: rows_ stays one batch long (in the cache, never reallocated after the
  // first), however far behind the tap is.
  constexpr std::size_t kBatch = 1024;
  auto& tap = tap_.tap();
  const std::size_t stride = tap.stride();
  for (;;) {
    rows_.clear();
    const std::size_t count = tap.drain(rows_, kBatch);
    if (count == 0) break;
    // Every series gets the whole batch in one call: the per-row work is the transposition.
    row_cycles_.resize(count);
    row_stamps_.resize(count);
    for (std::size_t r = 0; r < count; ++r) {
      row_cycles_[r] = static_cast<std::uint64_t>(rows_[r * stride]);
      row_stamps_[r] = static_cast<std::int64_t>(std::llround(rows_[r * stride + 1] * 1e9));
    }
    if (!first_cycle_) first_cycle_ = row_cycles_.front();
    for (std::size_t i = 0; i < series_.size(); ++i)
      recorder_->append_rows(series_[i], count, row_cycles_.data(), row_stamps_.data(), rows_.data() + tap.column(i),
                             stride);
    recorded_cycles_ += count;
    if (count < kBatch) break;
  }
  for (const auto& e : events_.since(event_cursor_)) recorder_->add_event(e.cycle, e.time_ns, e.kind, e.text);
}

// Writes what was drained to the file at most every record.flush_interval_s of wall time
// (always when `force`), so that a crash loses at most that much; the first write error ends
// the recording (failed_locked()).
void RunRecorder::flush_locked(bool force) {
  if (!recorder_) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_flush_ < std::chrono::duration<double>(pipeline_.record_settings().flush_interval_s))
    return;
  last_flush_ = now;
  if (auto st = recorder_->flush(); !st) {
    failed_locked(st.message());
    return;
  }
  flushed_cycles_ = recorded_cycles_;
}

// A recording that cannot be written (disk full, I/O error) stops here, cleanly: the tap
// closes, the file is closed as far as HDF5 can, the event and the summary say what the file
// holds and what was lost, and with record.on_error: stop the run faults (outputs safe).
void RunRecorder::failed_locked(const std::string& why) {
  tap_.open().store(false, std::memory_order_release);
  const bool stop_run = pipeline_.record_settings().stop_on_error;
  const std::uint64_t lost = recorded_cycles_ - flushed_cycles_;
  const Status closed = recorder_->close();
  std::string text = "recording " + path_ + " failed: " + why + "; recording stopped. The file keeps " +
                     std::to_string(flushed_cycles_) + " cycles (up to its last flush); " + std::to_string(lost) +
                     " cycles recorded after that are lost" +
                     (closed ? std::string() : " (closing it failed too: " + closed.message() + ")") +
                     (stop_run ? "; record.on_error: stop ends the run" : "; the run goes on (record.on_error: continue)");
  events_.post(stats_.last_time_ns.load(), stats_.cycles.load(), stop_run ? "fault" : "warning", text);
  Json j = Json::object();
  j["file"] = path_;
  j["cycles"] = flushed_cycles_;
  j["dropped"] = tap_.tap().dropped();
  j["lost"] = lost;
  j["error"] = why;
  j["complete"] = false;
  finished_.push(std::move(j));
  recorder_.reset();
  if (stop_run) scheduler_.request_fault("recording: " + why + " (record.on_error: stop)");
}

Status RunRecorder::close_locked() {
  if (!recorder_) return Status::error("not recording");
  tap_.open().store(false, std::memory_order_release);
  drain_locked();
  const auto dropped = tap_.tap().dropped();
  recorder_->set_attribute("dropped_cycles", static_cast<double>(dropped));
  recorder_->set_attribute("cycles", static_cast<double>(recorded_cycles_));
  recorder_->set_attribute("first_cycle", first_cycle_ ? static_cast<double>(*first_cycle_) : 0.0);
  // The run's timing from its start until now (not only the recorded cycles: the scheduler
  // keeps one set of statistics), so that `lode plot` shows what the summary prints.
  recorder_->set_attribute("timing", run_timing_json(pipeline_, stats_).dump(-1));
  // The digest covers every cycle the pipeline ran: it describes this file only when the
  // recording saw all of them (opened before the first cycle, closed after the last, none
  // dropped). Otherwise say why there is none rather than claim a wrong one.
  const bool whole_run = from_start_ && !running_.load() && dropped == 0;
  if (whole_run) {
    recorder_->set_attribute("output_digest", digest_.text());
    recorder_->set_attribute(kDigestAlgorithmKey, digest_algorithm_name(digest_.algorithm()));
  } else {
    recorder_->set_attribute("recording_partial",
                            !from_start_ ? "recording started mid-run (first cycle " +
                                                        std::to_string(first_cycle_.value_or(0)) +
                                                        "): no output digest"
                            : running_.load()      ? std::string("recording stopped mid-run: no output digest")
                                                  : "cycles dropped by the recorder: no output digest");
  }
  auto st = recorder_->close();
  Json j = Json::object();
  j["file"] = path_;
  j["cycles"] = st ? recorded_cycles_ : flushed_cycles_;
  j["dropped"] = tap_.tap().dropped();
  j["lost"] = st ? std::uint64_t{0} : recorded_cycles_ - flushed_cycles_;
  if (!st) j["error"] = st.message();
  j["complete"] = st.is_ok() && tap_.tap().dropped() == 0;
  finished_.push(std::move(j));
  recorder_.reset();
  return st;
}

ControlReply RunRecorder::handle(const ControlRequest& r) {
  ControlReply reply;
  reply.id = r.id;
  std::lock_guard lock(mutex_);
  if (r.kind == "record_start") {
    if (r.name.empty()) {
      reply.message = "record_start: give the file to write on the RT host (lode record --remote-start FILE)";
      return reply;
    }
    if (auto st = open_locked(r.name); !st) {
      reply.message = "record_start: " + st.message();
      return reply;
    }
    reply.ok = true;
    reply.message = "recording every output of '" + pipeline_.name() + "' to " + r.name;
    events_.post(stats_.last_time_ns.load(), stats_.cycles.load(), "record", reply.message);
  } else {
    const std::string path = path_;
    if (auto st = close_locked(); !st) {
      reply.message = "record_stop: " + st.message();
      return reply;
    }
    const auto cycles = recorded_cycles_;  // after close_locked(), which writes what was still in the tap
    reply.ok = true;
    reply.message = "closed " + path + " (" + std::to_string(cycles) + " cycles)";
    events_.post(stats_.last_time_ns.load(), stats_.cycles.load(), "record", reply.message);
  }
  return reply;
}

}  // namespace lode::cli
