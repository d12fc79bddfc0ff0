#include "plot_data.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <unordered_map>

#include "estimator_signals.hpp"

namespace lode::plot {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

std::string LoadedRecording::text(const std::string& key) const {
  const auto it = recording.text_attributes.find(key);
  return it == recording.text_attributes.end() ? "" : it->second;
}

std::optional<double> LoadedRecording::number(const std::string& key) const {
  const auto it = recording.number_attributes.find(key);
  if (it == recording.number_attributes.end()) return std::nullopt;
  return it->second;
}

const record::SeriesData* LoadedRecording::series(const std::string& name) const {
  for (const auto& s : recording.series)
    if (s.info.name == name) return &s;
  return nullptr;
}

Expected<LoadedRecording> open_recording(const std::string& path, PluginRegistry& registry) {
  // The attributes, the events and the names of the series: no series data yet.
  auto recording = record::read_recording(path, {"none", [](const std::string&, const std::string&) { return false; }});
  if (!recording) return recording.status();
  LoadedRecording loaded;
  loaded.path = path;
  loaded.label = std::filesystem::path(path).filename().string();
  loaded.recording = std::move(*recording);
  const std::string config = loaded.text("config");
  if (config.empty()) {
    loaded.notes.push_back(path + ": no `config` attribute (a `lode record` of DDS topics): roles found by name");
    return loaded;
  }
  // The configuration as it was run: the same loader gives the same monitor: section and
  // shadows as the run had. A replay's configuration reads its source recording (io.replay),
  // which must still be where it was.
  Diagnostics diagnostics;
  loaded.pipeline = Pipeline::load_text(config, loaded.text("config_file").empty() ? path : loaded.text("config_file"),
                                        registry, diagnostics);
  if (!loaded.pipeline) {
    loaded.notes.push_back(path + ": its configuration no longer loads (roles found by name): " +
                           diagnostics.format());
    return loaded;
  }
  // Every series a figure or the run summary reads: the roles and the monitored signals.
  std::set<std::string> wanted;
  const SeriesRoles roles = find_roles(loaded);
  for (const std::string* name : {&roles.reference, &roles.truth})
    if (!name->empty()) wanted.insert(*name);
  for (const auto& e : roles.estimates) wanted.insert(e.series);
  const MonitorSpec& mon = loaded.pipeline->monitor();
  for (const auto* s : {&mon.show, &mon.estimate, &mon.truth, &mon.reference})
    if (*s) wanted.insert((*s)->name());
  for (const auto& s : mon.record) wanted.insert(s.name());
  loaded.plotted = {"plot", [wanted](const std::string& name, const std::string&) { return wanted.count(name) > 0; }};
  return loaded;
}

Status check_replay_of(const LoadedRecording& recording, const LoadedRecording& replay, std::vector<std::string>& notes) {
  std::size_t compared = 0;
  for (const auto& theirs : replay.recording.series) {
    if (theirs.info.kind != "raw") continue;
    const record::SeriesData* ours = recording.series(theirs.info.name);
    if (!ours || ours->width() != theirs.width()) continue;
    ++compared;
    const std::size_t rows = std::min(ours->rows(), theirs.rows());
    const std::size_t width = ours->width();
    for (std::size_t k = 0; k < rows; ++k) {
      const bool same = ours->cycle[k] == theirs.cycle[k] &&
                        std::memcmp(&ours->values[k * width], &theirs.values[k * width], width * sizeof(double)) == 0;
      if (!same)
        return Status::error(replay.path + " is not a replay of " + recording.path + ": its " + theirs.info.name +
                             " differs from the recording's at row " + std::to_string(k) + " (cycle " +
                             std::to_string(theirs.cycle[k]) +
                             "); further files must be replays of the first (lode replay " + recording.path + ")");
    }
  }
  if (compared == 0)
    notes.push_back(replay.path + ": no raw series in common with " + recording.path +
                    ", so it could not be checked to be a replay of it");
  return Status::ok();
}

Expected<std::uint64_t> plotted_bytes(const LoadedRecording& loaded) {
  auto cost = record::read_cost(loaded.path, loaded.plotted);
  if (!cost) return cost.status();
  return cost->bytes;
}

Status read_plotted(LoadedRecording& loaded) {
  auto recording = record::read_recording(loaded.path, loaded.plotted);
  if (!recording) return recording.status();
  loaded.recording = std::move(*recording);
  for (const auto& w : loaded.recording.warnings) loaded.notes.push_back(loaded.path + ": " + w);
  return Status::ok();
}

Expected<LoadedRecording> load_recording(const std::string& path, PluginRegistry& registry) {
  auto loaded = open_recording(path, registry);
  if (!loaded) return loaded.status();
  if (Status s = read_plotted(*loaded); !s) return s;
  return loaded;
}

SeriesRoles find_roles(const LoadedRecording& loaded) {
  if (!loaded.pipeline) return find_roles_by_name(loaded.recording);
  const Pipeline& p = *loaded.pipeline;
  const MonitorSpec& mon = p.monitor();
  SeriesRoles roles;
  if (mon.reference) roles.reference = mon.reference->name();
  if (mon.truth) roles.truth = mon.truth->name();
  roles.hold_start_s = mon.hold_start_s;
  roles.hold_end_s = mon.hold_end_s;
  roles.settle_band = mon.settle_band;
  std::vector<std::string> notes;
  for (const auto& e : cli::estimator_signals(p, notes)) roles.estimates.push_back({e.signal.name(), e.role});
  // The summary compares monitor.record outputs with the truth when they have its shape:
  // they are estimates too (GLSDC's measured pose beside the Kalman filter's).
  const std::size_t width = mon.truth ? mon.truth->size() : 0;
  for (const auto& s : mon.record) {
    const bool known = std::any_of(roles.estimates.begin(), roles.estimates.end(),
                                   [&](const auto& e) { return e.series == s.name(); });
    if (!known && s.size() == width && s.name() != roles.truth && s.name() != roles.reference)
      roles.estimates.push_back({s.name(), "monitor.record"});
  }
  return roles;
}

SeriesRoles find_roles_by_name(const record::Recording& recording) {
  SeriesRoles roles;
  const auto port_of = [](const std::string& name) {
    const auto dot = name.rfind('.');
    return dot == std::string::npos ? name : name.substr(dot + 1);
  };
  const auto block_of = [](const std::string& name) { return name.substr(0, name.find('.')); };
  for (const auto& s : recording.series) {
    const std::string& name = s.info.name;
    if (roles.truth.empty() && port_of(name) == "truth") roles.truth = name;
    const bool reference_name = block_of(name) == "ref" || block_of(name) == "reference" || port_of(name) == "reference";
    if (roles.reference.empty() && reference_name) roles.reference = name;
  }
  const record::SeriesData* shape = nullptr;
  for (const auto& s : recording.series)
    if (s.info.name == (roles.truth.empty() ? roles.reference : roles.truth)) shape = &s;
  if (!shape) return roles;
  for (const auto& s : recording.series) {
    if (s.info.name == roles.truth || s.info.name == roles.reference || s.info.kind == "raw") continue;
    if (s.info.names == shape->info.names && s.info.units == shape->info.units)
      roles.estimates.push_back({s.info.name, "by name"});
  }
  return roles;
}

TimeGrid time_grid(const record::SeriesData& series) {
  TimeGrid grid;
  grid.time_s.reserve(series.rows());
  for (const auto ns : series.stamp_ns) grid.time_s.push_back(static_cast<double>(ns) * 1e-9);
  if (series.rows() < 2) return grid;
  const std::int64_t step = series.stamp_ns[1] - series.stamp_ns[0];
  grid.uniform = step > 0;
  for (std::size_t k = 2; k < series.rows() && grid.uniform; ++k)
    grid.uniform = series.stamp_ns[k] - series.stamp_ns[k - 1] == step;
  grid.t0 = grid.time_s.front();
  grid.dt = static_cast<double>(step) * 1e-9;
  return grid;
}

const Trace* AxisTraces::find_role(const std::string& role) const {
  for (const auto& t : traces)
    if (t.role == role) return &t;
  return nullptr;
}

namespace {

/// Element `element` of `series` on the primary's rows. The same cycles row for row is the
/// common case (one run, or a replay of it); otherwise rows are matched by cycle.
std::vector<double> column_on_grid(const record::SeriesData& series, std::size_t element,
                                   const record::SeriesData& primary) {
  const std::size_t rows = primary.rows();
  std::vector<double> out(rows, kNaN);
  const std::size_t width = series.width();
  if (series.cycle == primary.cycle) {
    for (std::size_t k = 0; k < rows; ++k) out[k] = series.values[k * width + element];
    return out;
  }
  std::unordered_map<std::uint64_t, std::size_t> row_of_cycle;
  row_of_cycle.reserve(series.rows());
  for (std::size_t k = 0; k < series.rows(); ++k) row_of_cycle.emplace(series.cycle[k], k);
  for (std::size_t k = 0; k < rows; ++k) {
    const auto it = row_of_cycle.find(primary.cycle[k]);
    if (it != row_of_cycle.end()) out[k] = series.values[it->second * width + element];
  }
  return out;
}

}  // namespace

PlotSignals collect_axes(const std::vector<const LoadedRecording*>& files, const std::vector<SeriesRoles>& roles) {
  PlotSignals out;
  auto& axes = out.axes;
  if (files.empty()) return out;
  const LoadedRecording& primary = *files.front();
  const SeriesRoles& primary_roles = roles.front();
  // The axes are the truth's elements (else the reference's, else the first estimate's).
  const record::SeriesData* shape = primary.series(primary_roles.truth);
  if (!shape) shape = primary.series(primary_roles.reference);
  if (!shape && !primary_roles.estimates.empty()) shape = primary.series(primary_roles.estimates.front().series);
  if (!shape) return out;
  const record::SeriesData* grid_series = shape;
  out.grid = time_grid(*grid_series);
  for (std::size_t i = 0; i < shape->width(); ++i) axes.push_back({shape->info.names[i], shape->info.units[i], {}});

  // Bit for bit: a NaN row (a cycle the file lacks) equals only the same NaN.
  const auto same_bits = [](const std::vector<double>& a, const std::vector<double>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
  };
  const auto add = [&](const LoadedRecording& file, const std::string& name, const std::string& role,
                       const std::string& detail, bool mark_file) {
    const record::SeriesData* s = file.series(name);
    if (!s) return;
    std::vector<std::pair<AxisTraces*, Trace>> found;
    for (auto& axis : axes) {
      const auto it = std::find(s->info.names.begin(), s->info.names.end(), axis.name);
      if (it == s->info.names.end()) continue;
      Trace t;
      t.label = mark_file ? name + " @ " + file.label : name;
      t.role = role;
      t.detail = detail;
      t.values = column_on_grid(*s, static_cast<std::size_t>(it - s->info.names.begin()), *grid_series);
      found.emplace_back(&axis, std::move(t));
    }
    if (found.empty()) return;
    // A replay through the recorded configuration reproduces the recorded estimates exactly:
    // drawn again they hide each other and crowd the legend. Left out only when every axis
    // agrees with the same earlier trace, so a difference anywhere keeps both.
    if (mark_file) {
      for (const Trace& earlier : found.front().first->traces) {
        if (earlier.role != role || earlier.label.substr(0, earlier.label.find(" @ ")) != name) continue;
        const bool everywhere = std::all_of(found.begin(), found.end(), [&](const auto& f) {
          const auto same = std::find_if(f.first->traces.begin(), f.first->traces.end(),
                                         [&](const Trace& t) { return t.label == earlier.label; });
          return same != f.first->traces.end() && same_bits(same->values, f.second.values);
        });
        if (everywhere) {
          out.notes.push_back(found.front().second.label + " is bit-identical to " + earlier.label + ": drawn once");
          return;
        }
      }
    }
    for (auto& [axis, trace] : found) axis->traces.push_back(std::move(trace));
  };
  add(primary, primary_roles.reference, "reference", "monitor.reference", false);
  add(primary, primary_roles.truth, "truth", "monitor.truth", false);
  for (std::size_t f = 0; f < files.size(); ++f)
    for (const auto& e : roles[f].estimates) add(*files[f], e.series, "estimate", e.role, f > 0);
  return out;
}

std::vector<AxisTraces> estimation_errors(const std::vector<AxisTraces>& axes) {
  std::vector<AxisTraces> errors;
  for (const auto& axis : axes) {
    const Trace* truth = axis.find_role("truth");
    if (!truth) continue;
    AxisTraces e{axis.name, axis.unit, {}};
    for (const auto& t : axis.traces) {
      if (t.role != "estimate") continue;
      Trace error{t.label + " - truth", "error", t.detail, std::vector<double>(t.values.size()), t.label, truth->label};
      for (std::size_t k = 0; k < t.values.size(); ++k) error.values[k] = t.values[k] - truth->values[k];
      e.traces.push_back(std::move(error));
    }
    if (!e.traces.empty()) errors.push_back(std::move(e));
  }
  return errors;
}

std::vector<MinMaxLevel> min_max_pyramid(const std::vector<double>& values, std::size_t first_bucket,
                                         std::size_t factor, std::size_t coarsest) {
  std::vector<MinMaxLevel> levels;
  if (values.size() <= first_bucket || first_bucket == 0 || factor < 2) return levels;
  // fmin/fmax return the other operand when one is NaN: NaN samples are skipped, and a
  // bucket of NaN only stays NaN.
  const auto reduce = [](const std::vector<double>& lo_in, const std::vector<double>& hi_in, std::size_t group,
                         MinMaxLevel& out) {
    const std::size_t n = (lo_in.size() + group - 1) / group;
    out.min.assign(n, kNaN);
    out.max.assign(n, kNaN);
    for (std::size_t b = 0; b < n; ++b) {
      const std::size_t end = std::min(lo_in.size(), (b + 1) * group);
      double lo = kNaN, hi = kNaN;
      for (std::size_t k = b * group; k < end; ++k) {
        lo = std::fmin(lo, lo_in[k]);
        hi = std::fmax(hi, hi_in[k]);
      }
      out.min[b] = lo;
      out.max[b] = hi;
    }
  };
  MinMaxLevel first;
  first.bucket = first_bucket;
  reduce(values, values, first_bucket, first);
  levels.push_back(std::move(first));
  while (levels.back().min.size() > coarsest) {
    MinMaxLevel next;
    next.bucket = levels.back().bucket * factor;
    reduce(levels.back().min, levels.back().max, factor, next);
    levels.push_back(std::move(next));
  }
  return levels;
}

}  // namespace lode::plot
