#include "plot_html.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>

#include "analysis.hpp"
#include "plot_assets.hpp"

namespace lode::plot {

std::string base64(const void* data, std::size_t size) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* bytes = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= size; i += 3) {
    const std::uint32_t v = (std::uint32_t{bytes[i]} << 16) | (std::uint32_t{bytes[i + 1]} << 8) | bytes[i + 2];
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i < size) {
    std::uint32_t v = std::uint32_t{bytes[i]} << 16;
    if (i + 1 < size) v |= std::uint32_t{bytes[i + 1]} << 8;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < size ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

namespace {

// The page reads the blobs with DataView/typed arrays in the machine's byte order; every
// platform lodestone builds on (x86-64, AArch64) is little-endian, as the format says.
static_assert(std::endian::native == std::endian::little, "report blobs are little-endian");

template <typename Stored>
nlohmann::json add_chunks(std::vector<std::string>& blobs, const std::vector<double>& values, double offset) {
  nlohmann::json ids = nlohmann::json::array();
  std::vector<Stored> chunk;
  for (std::size_t first = 0; first < values.size(); first += kBlobSamples) {
    const std::size_t n = std::min(kBlobSamples, values.size() - first);
    chunk.resize(n);
    for (std::size_t k = 0; k < n; ++k) chunk[k] = static_cast<Stored>(values[first + k] - offset);
    ids.push_back(blobs.size());
    blobs.push_back(base64(chunk.data(), n * sizeof(Stored)));
  }
  return {{"length", values.size()}, {"chunk", kBlobSamples}, {"blobs", std::move(ids)}};
}

/// Midway between the finite extremes: the Float32 offsets are then at most half the range.
double offset_for(const std::vector<double>& values) {
  double lo = INFINITY, hi = -INFINITY;
  for (const double v : values)
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  return lo <= hi ? 0.5 * (lo + hi) : 0.0;
}

nlohmann::json to_nlohmann(const Json& j) { return nlohmann::json::parse(j.dump(-1)); }

/// A value nlohmann writes as JSON: NaN and infinities become null, as in the run summary.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::string html_escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

nlohmann::json axes_json(const std::vector<AxisTraces>& axes, BlobStore& blobs) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& axis : axes) {
    nlohmann::json traces = nlohmann::json::array();
    for (const auto& t : axis.traces) traces.push_back(trace_json(t, blobs));
    // The page shows values in the summary's units (um, urad, ...) for the largest value drawn.
    double magnitude = 0.0;
    for (const auto& t : axis.traces)
      for (const double v : t.values)
        if (std::isfinite(v)) magnitude = std::max(magnitude, std::abs(v));
    const auto [scale, unit] = analysis::display_scale(axis.unit, magnitude);
    out.push_back({{"axis", axis.name}, {"unit", axis.unit}, {"display", {{"scale", scale}, {"unit", unit}}},
                   {"traces", std::move(traces)}});
  }
  return out;
}

nlohmann::json files_json(const std::vector<const LoadedRecording*>& files) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto* f : files) {
    nlohmann::json j = {{"label", f->label}, {"path", f->path}};
    for (const char* key : {"source", "pipeline", "config_file", "created_utc", "host", "output_digest",
                            "recording_partial"})
      if (!f->text(key).empty()) j[key] = f->text(key);
    for (const char* key : {"rate_hz", "cycles", "dropped_cycles"})
      if (const auto v = f->number(key)) j[key] = *v;
    out.push_back(std::move(j));
  }
  return out;
}

/// The summary's steps with what a plot of each needs besides: the reference after the step
/// and the end of its analysis window (the next step of any axis, else the end).
nlohmann::json steps_json(const nlohmann::json& summary, const PlotSignals& signals) {
  nlohmann::json steps = nlohmann::json::array();
  if (!summary.contains("steps")) return steps;
  const auto& time = signals.grid.time_s;
  std::vector<double> starts;
  for (const auto& s : summary["steps"]) starts.push_back(s.value("time_s", 0.0));
  for (const auto& s : summary["steps"]) {
    nlohmann::json step = s;
    const double t = s.value("time_s", 0.0);
    double end = time.empty() ? t : time.back();
    for (const double other : starts)
      if (other > t) end = std::min(end, other);
    step["window_end_s"] = end;
    const auto axis = std::find_if(signals.axes.begin(), signals.axes.end(),
                                   [&](const AxisTraces& a) { return a.name == s.value("axis", ""); });
    if (axis != signals.axes.end()) {
      step["unit"] = axis->unit;
      const auto at = std::lower_bound(time.begin(), time.end(), t);
      if (const Trace* ref = axis->find_role("reference"); ref && at != time.end())
        step["final_reference"] = number(ref->values[static_cast<std::size_t>(at - time.begin())]);
    }
    steps.push_back(std::move(step));
  }
  return steps;
}

nlohmann::json spectra_json(const std::vector<AxisSpectra>& spectra) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& axis : spectra) {
    nlohmann::json traces = nlohmann::json::array();
    for (const auto& [label, s] : axis.spectra) {
      // Drop the DC bin: the mean was removed, and a log axis cannot show 0 Hz.
      std::vector<double> f(s.frequency_hz.begin() + 1, s.frequency_hz.end());
      nlohmann::json density = nlohmann::json::array();
      for (std::size_t b = 1; b < s.density.size(); ++b) density.push_back(number(s.density[b]));
      traces.push_back({{"label", label}, {"segments", s.segments}, {"frequency_hz", std::move(f)},
                        {"density", std::move(density)}});
    }
    out.push_back({{"axis", axis.axis}, {"unit", axis.unit}, {"traces", std::move(traces)}});
  }
  return out;
}

/// Every figure of the page, in order, with the id `#figure=<id>` shows alone (what --png
/// photographs). The page draws exactly this list.
nlohmann::json figures_json(const nlohmann::json& report) {
  nlohmann::json figures = nlohmann::json::array();
  const auto add = [&](const std::string& id, const std::string& title) {
    figures.push_back({{"id", id}, {"title", title}});
  };
  for (std::size_t i = 0; i < report["signals"].size(); ++i)
    add("signals-" + std::to_string(i), "signals: " + report["signals"][i]["axis"].get<std::string>());
  for (std::size_t i = 0; i < report["errors"].size(); ++i)
    add("errors-" + std::to_string(i), "estimation error: " + report["errors"][i]["axis"].get<std::string>());
  for (std::size_t i = 0; i < report["steps"].size(); ++i)
    add("step-" + std::to_string(i), "step response " + std::to_string(i + 1) + ": " +
                                         report["steps"][i].value("axis", std::string()));
  for (std::size_t i = 0; i < report["psd"].size(); ++i)
    add("psd-" + std::to_string(i), "noise PSD: " + report["psd"][i]["axis"].get<std::string>());
  if (report["timing"].is_object()) {
    add("timing-latency", "wake-up latency and cycle time");
    add("timing-blocks", "execution time per block");
    add("timing-overruns", "overruns");
  }
  return figures;
}

}  // namespace

nlohmann::json BlobStore::add_float32(const std::vector<double>& values, double offset) {
  nlohmann::json j = add_chunks<float>(blobs_, values, offset);
  j["offset"] = offset;
  return j;
}

nlohmann::json BlobStore::add_float64(const std::vector<double>& values) {
  return add_chunks<double>(blobs_, values, 0.0);
}

std::string BlobStore::elements() const {
  std::string out;
  out.reserve(bytes() + blobs_.size() * 64);
  for (std::size_t i = 0; i < blobs_.size(); ++i) {
    out += "<script type=\"application/x-lode-blob\" id=\"b" + std::to_string(i) + "\">";
    out += blobs_[i];
    out += "</script>\n";
  }
  return out;
}

std::size_t BlobStore::bytes() const {
  std::size_t n = 0;
  for (const auto& b : blobs_) n += b.size();
  return n;
}

nlohmann::json trace_json(const Trace& trace, BlobStore& blobs) {
  const double offset = offset_for(trace.values);
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& level : min_max_pyramid(trace.values))
    levels.push_back({{"bucket", level.bucket},
                      {"min", blobs.add_float32(level.min, offset)},
                      {"max", blobs.add_float32(level.max, offset)}});
  nlohmann::json j = {{"label", trace.label}, {"role", trace.role}, {"detail", trace.detail},
                      {"levels", std::move(levels)}};
  // The min/max of a difference is not the difference of min/max, so an error keeps its own
  // pyramid; its samples are the difference of two stored curves (a third less to store).
  if (trace.minuend.empty()) j["samples"] = blobs.add_float32(trace.values, offset);
  else j["difference"] = {trace.minuend, trace.subtrahend};
  return j;
}

nlohmann::json report_json(const ReportInput& in, BlobStore& blobs) {
  const LoadedRecording& primary = *in.files.front();
  const TimeGrid& grid = in.signals->grid;
  nlohmann::json j;
  j["title"] = in.title;
  j["files"] = files_json(in.files);
  j["notes"] = in.notes;
  if (grid.uniform)
    j["time"] = {{"t0", grid.t0}, {"dt", grid.dt}, {"length", grid.size()}};
  else
    j["time"] = {{"samples", blobs.add_float64(grid.time_s)}, {"length", grid.size()}};
  j["range"] = grid.size() ? nlohmann::json::array({grid.time_s.front(), grid.time_s.back()}) : nlohmann::json::array({0, 1});
  j["hold"] = {in.hold.start_s, in.hold.end_s};
  nlohmann::json events = nlohmann::json::array();
  for (const auto& e : primary.recording.events)
    events.push_back({{"t", static_cast<double>(e.stamp_ns) * 1e-9}, {"cycle", e.cycle}, {"kind", e.kind},
                      {"text", e.text}});
  j["events"] = std::move(events);
  j["timing"] = nullptr;
  j["overruns"] = nlohmann::json::array();
  if (const std::string timing = primary.text("timing"); !timing.empty()) {
    j["timing"] = nlohmann::json::parse(timing, nullptr, false);
    const double rate = j["timing"].value("rate_hz", primary.number("rate_hz").value_or(0.0));
    if (rate > 0 && j["timing"].contains("overrun_cycles"))
      for (const auto& cycle : j["timing"]["overrun_cycles"]) j["overruns"].push_back(cycle.get<double>() / rate);
  }
  j["signals"] = axes_json(in.signals->axes, blobs);
  j["errors"] = axes_json(*in.errors, blobs);
  nlohmann::json table = nlohmann::json::array();
  for (const auto& e : *in.error_table)
    table.push_back({{"axis", e.axis}, {"unit", e.unit}, {"estimator", e.estimator}, {"detail", e.detail},
                     {"bias", number(e.bias)}, {"rms", number(e.rms)}, {"max_abs", number(e.max_abs)},
                     {"hold_std", number(e.hold_std)}, {"samples", e.samples}});
  j["error_table"] = std::move(table);
  j["summary"] = to_nlohmann(in.summary);
  j["steps"] = steps_json(j["summary"], *in.signals);
  j["psd"] = spectra_json(*in.spectra);
  j["config"] = primary.text("config");
  j["figures"] = figures_json(j);
  return j;
}

Report report_html(const ReportInput& input) {
  BlobStore blobs;
  const nlohmann::json document = report_json(input, blobs);
  Report report;
  for (const auto& f : document["figures"]) report.figures.push_back(f["id"].get<std::string>());
  report.blob_bytes = blobs.bytes();
  std::string data = document.dump();
  // "</" inside a <script> element would end it: JSON allows "<\/" for the same text.
  for (std::size_t at = data.find("</"); at != std::string::npos; at = data.find("</", at + 3)) data.insert(at + 1, "\\");
  const std::map<std::string, std::string_view> parts = {
      {"TITLE", {}}, {"UPLOT_CSS", assets::kUplotCss}, {"REPORT_CSS", assets::kReportCss},
      {"DATA", data}, {"BLOBS", {}}, {"UPLOT_JS", assets::kUplotJs}, {"REPORT_JS", assets::kReportJs}};
  const std::string title = html_escape(input.title);
  const std::string blob_elements = blobs.elements();
  // One pass over the template only: inserted text is never searched for placeholders.
  const std::string_view page = assets::kReportHtml;
  std::string& out = report.html;
  out.reserve(page.size() + data.size() + blob_elements.size() + assets::kUplotJs.size() + assets::kReportJs.size());
  std::size_t at = 0;
  while (true) {
    const std::size_t open = page.find("{{", at);
    const std::size_t close = open == std::string_view::npos ? open : page.find("}}", open);
    if (close == std::string_view::npos) break;
    out.append(page.substr(at, open - at));
    const std::string name(page.substr(open + 2, close - open - 2));
    if (name == "TITLE") out += title;
    else if (name == "BLOBS") out += blob_elements;
    else if (const auto it = parts.find(name); it != parts.end()) out.append(it->second);
    else out.append(page.substr(open, close + 2 - open));
    at = close + 2;
  }
  out.append(page.substr(at));
  return report;
}

}  // namespace lode::plot
