// The `lode plot` report as one self-contained HTML file: the page template, its script and
// style and the chart library (uPlot) are compiled into `lode` (plot_assets.hpp, generated
// from apps/lode/plot/ at build time), and every number is inlined, so the file opens
// offline and from anywhere.
//
// Data layout in the page: a JSON document (<script type="application/json">) describes
// every section; long arrays are not JSON numbers but base64 little-endian Float32 (values
// minus a per-trace double offset, so that a micrometre signal on a metre offset keeps its
// resolution) or Float64 (times), each in its own <script type="application/x-lode-blob">
// element of at most kBlobSamples values, which the page decodes only when a view needs it.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "plot_data.hpp"
#include "plot_metrics.hpp"

namespace lode::plot {

/// Samples per blob: 12288 Float32 values are 65536 base64 characters, the longest text node
/// Chromium keeps in one piece (a longer one is split, and reading it back joins the pieces).
inline constexpr std::size_t kBlobSamples = 12288;

/// Base64 (RFC 4648, with padding) of `size` bytes.
std::string base64(const void* data, std::size_t size);

/// Collects the binary arrays of a report and gives each an id the JSON refers to.
class BlobStore {
 public:
  /// `values` as Float32 offsets from `offset`, in blobs of kBlobSamples:
  /// {"offset": o, "length": n, "chunk": kBlobSamples, "blobs": [ids]}.
  nlohmann::json add_float32(const std::vector<double>& values, double offset);
  /// `values` as Float64: {"length": n, "chunk": kBlobSamples, "blobs": [ids]}.
  nlohmann::json add_float64(const std::vector<double>& values);
  /// Every blob as a <script type="application/x-lode-blob" id="b<N>"> element.
  [[nodiscard]] std::string elements() const;
  [[nodiscard]] std::size_t bytes() const;

 private:
  std::vector<std::string> blobs_;
};

/// One curve for the page: its samples and its min/max pyramid (same offset), so the page
/// draws min/max per pixel at any zoom and the samples themselves once few enough are shown.
nlohmann::json trace_json(const Trace& trace, BlobStore& blobs);

/// Everything the report shows.
struct ReportInput {
  std::string title;
  std::vector<const LoadedRecording*> files;
  const PlotSignals* signals = nullptr;
  const std::vector<AxisTraces>* errors = nullptr;
  const std::vector<EstimatorError>* error_table = nullptr;
  const std::vector<AxisSpectra>* spectra = nullptr;
  HoldWindow hold;
  Json summary;  ///< run_summary() of the primary recording
  std::vector<std::string> notes;
};

/// The report's JSON document (blobs go to `blobs`).
nlohmann::json report_json(const ReportInput& input, BlobStore& blobs);

struct Report {
  std::string html;                  ///< the whole page
  std::vector<std::string> figures;  ///< ids of its figures, in order (`report.html#figure=<id>`)
  std::size_t blob_bytes = 0;        ///< of which base64 arrays
};
Report report_html(const ReportInput& input);

}  // namespace lode::plot
