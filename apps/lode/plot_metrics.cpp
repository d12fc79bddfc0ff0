#include "plot_metrics.hpp"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include "analysis.hpp"
#include "run_analysis.hpp"

namespace lode::plot {

Json run_summary(const LoadedRecording& loaded, std::vector<std::string>& notes) {
  if (!loaded.pipeline) return Json::object();
  cli::RunAnalysis analysis(*loaded.pipeline);
  analysis.print_to(nullptr);
  const SignalTap& tap = analysis.tap();
  // Each tapped signal's recorded series; rows are laid out as the tap lays out its records.
  std::vector<const record::SeriesData*> sources;
  std::size_t rows = 0;
  for (const auto& signal : tap.signals()) {
    const record::SeriesData* s = loaded.series(signal.name());
    if (!s || s->width() != signal.size()) {
      notes.push_back(loaded.path + ": " + signal.name() + " (monitored) is not in the recording: no summary");
      return Json::object();
    }
    if (!sources.empty() && s->cycle != sources.front()->cycle) {
      notes.push_back(loaded.path + ": the monitored series were not recorded in the same cycles: no summary");
      return Json::object();
    }
    sources.push_back(s);
    rows = s->rows();
  }
  std::vector<double> row(tap.stride());
  for (std::size_t k = 0; k < rows; ++k) {
    row[0] = static_cast<double>(sources.front()->cycle[k]);
    row[1] = static_cast<double>(sources.front()->stamp_ns[k]) * 1e-9;
    for (std::size_t i = 0; i < sources.size(); ++i) {
      const std::size_t width = sources[i]->width();
      std::copy_n(sources[i]->values.data() + k * width, width, row.data() + tap.column(i));
    }
    analysis.add_row(row.data());
  }
  return analysis.finish();
}

HoldWindow hold_window(const SeriesRoles& roles, const TimeGrid& grid) {
  HoldWindow hold;
  const double last = grid.size() ? grid.time_s.back() : 0.0;
  // As RunAnalysis: no window set means from the start to the end of the run.
  if (roles.hold_end_s > roles.hold_start_s) {
    hold.start_s = roles.hold_start_s;
    hold.end_s = std::min(roles.hold_end_s, last);
  } else {
    hold.end_s = last;
  }
  return hold;
}

std::vector<EstimatorError> estimator_errors(const std::vector<AxisTraces>& axes, const TimeGrid& grid,
                                             const HoldWindow& hold) {
  std::vector<EstimatorError> out;
  constexpr double kForever = std::numeric_limits<double>::infinity();
  for (const auto& axis : axes) {
    const Trace* truth = axis.find_role("truth");
    if (!truth) continue;
    for (const auto& t : axis.traces) {
      if (t.role != "estimate") continue;
      // The summary's accumulators: the start-up transient before the hold window is not an
      // estimation error.
      analysis::WindowAccumulator error(1, hold.start_s, kForever);
      analysis::WindowAccumulator noise(1, hold.start_s, hold.end_s);
      for (std::size_t k = 0; k < grid.size(); ++k) {
        if (std::isnan(t.values[k]) || std::isnan(truth->values[k])) continue;
        error.add(grid.time_s[k], &t.values[k], &truth->values[k]);
        noise.add(grid.time_s[k], &t.values[k]);
      }
      const auto e = error.result().front();
      out.push_back({axis.name, axis.unit, t.label, t.detail, e.mean, e.rms, e.max_abs, noise.result().front().std,
                     e.samples});
    }
  }
  return out;
}

std::size_t welch_segment(std::size_t samples) {
  std::size_t segment = 8192;
  // k half-overlapping segments of length L need (k + 1) * L / 2 samples.
  while (segment > 64 && 9 * segment / 2 > samples) segment /= 2;
  return 9 * segment / 2 > samples ? 0 : segment;
}

Spectrum welch_psd(const std::vector<double>& values, double fs, std::size_t segment) {
  Spectrum out;
  if (segment < 2 || fs <= 0) return out;
  const std::size_t bins = segment / 2 + 1;
  std::vector<double> window(segment);
  double window_power = 0.0;
  for (std::size_t k = 0; k < segment; ++k) {
    window[k] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(segment));
    window_power += window[k] * window[k];
  }
  out.density.assign(bins, 0.0);
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::vector<double> piece(segment);
  std::vector<std::complex<double>> spectrum;
  const std::size_t hop = segment / 2;
  for (std::size_t start = 0; start + segment <= values.size(); start += hop) {
    const auto first = values.begin() + static_cast<std::ptrdiff_t>(start);
    const auto last = first + static_cast<std::ptrdiff_t>(segment);
    if (std::any_of(first, last, [](double v) { return std::isnan(v); })) continue;
    double mean = 0.0;
    for (auto it = first; it != last; ++it) mean += *it;
    mean /= static_cast<double>(segment);
    for (std::size_t k = 0; k < segment; ++k) piece[k] = (first[static_cast<std::ptrdiff_t>(k)] - mean) * window[k];
    fft.fwd(spectrum, piece);
    for (std::size_t b = 0; b < bins; ++b) out.density[b] += std::norm(spectrum[b]);
    ++out.segments;
  }
  if (out.segments == 0) {
    out.density.clear();
    return out;
  }
  // One-sided: every bin but DC and Nyquist carries the power of its negative twin.
  const double scale = 1.0 / (fs * window_power * static_cast<double>(out.segments));
  out.frequency_hz.resize(bins);
  for (std::size_t b = 0; b < bins; ++b) {
    out.frequency_hz[b] = static_cast<double>(b) * fs / static_cast<double>(segment);
    out.density[b] *= (b == 0 || b == bins - 1) ? scale : 2.0 * scale;
  }
  return out;
}

std::vector<AxisSpectra> hold_spectra(const std::vector<AxisTraces>& axes, const TimeGrid& grid,
                                      const HoldWindow& hold) {
  std::vector<AxisSpectra> out;
  if (grid.size() < 2 || !(grid.dt > 0)) return out;
  const auto begin = std::lower_bound(grid.time_s.begin(), grid.time_s.end(), hold.start_s);
  const auto end = std::upper_bound(grid.time_s.begin(), grid.time_s.end(), hold.end_s);
  const auto from = static_cast<std::size_t>(begin - grid.time_s.begin());
  const auto to = static_cast<std::size_t>(end - grid.time_s.begin());
  const std::size_t segment = welch_segment(to > from ? to - from : 0);
  if (segment == 0) return out;
  for (const auto& axis : axes) {
    AxisSpectra a{axis.name, axis.unit, {}};
    for (const auto& t : axis.traces) {
      if (t.role != "truth" && t.role != "estimate") continue;
      const std::vector<double> window(t.values.begin() + static_cast<std::ptrdiff_t>(from),
                                       t.values.begin() + static_cast<std::ptrdiff_t>(to));
      Spectrum s = welch_psd(window, 1.0 / grid.dt, segment);
      if (s.segments > 0) a.spectra.emplace_back(t.label, std::move(s));
    }
    if (!a.spectra.empty()) out.push_back(std::move(a));
  }
  return out;
}

}  // namespace lode::plot
