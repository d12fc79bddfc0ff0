// The figures of a `lode plot` report: the run summary recomputed from the recording (the
// same RunAnalysis `lode run` prints at its end: noise, errors, every step response), each
// estimator's error, and the power spectral density of the noise in the hold window.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lode/sdk/json.hpp"
#include "plot_data.hpp"

namespace lode::plot {

/// What `lode run` printed at the end of the recorded run, recomputed from the recording's
/// rows by cli::RunAnalysis (position noise, estimation and tracking errors, steps); an
/// empty object when the recording has no loadable pipeline or lacks a monitored series
/// (`notes` says which).
Json run_summary(const LoadedRecording& loaded, std::vector<std::string>& notes);

/// The hold window [t0, t1] of the summary (t1 = the last sample when the monitor sets none).
struct HoldWindow {
  double start_s = 0.0, end_s = 0.0;
};
HoldWindow hold_window(const SeriesRoles& roles, const TimeGrid& grid);

/// Error statistics of one estimate on one axis, as the summary computes them (from the
/// start of the hold window to the end), and its noise (std) inside the hold window.
struct EstimatorError {
  std::string axis, unit, estimator, detail;
  double bias = 0.0, rms = 0.0, max_abs = 0.0, hold_std = 0.0;
  std::size_t samples = 0;
};
std::vector<EstimatorError> estimator_errors(const std::vector<AxisTraces>& axes, const TimeGrid& grid,
                                             const HoldWindow& hold);

/// One-sided power spectral density by Welch's method (Welch 1967): Hann-windowed segments
/// of `segment` samples (a power of two) overlapping by half, each with its mean removed,
/// periodograms averaged and scaled to unit^2/Hz so that the integral over frequency is the
/// variance. NaN samples end a stretch; segments never span one.
struct Spectrum {
  std::vector<double> frequency_hz, density;
  std::size_t segments = 0;
};
Spectrum welch_psd(const std::vector<double>& values, double sample_rate_hz, std::size_t segment);

/// The segment length for `samples`: the largest power of two giving at least 8 half-overlapping
/// segments, between 64 and 8192 (0 when there are too few samples for a spectrum).
std::size_t welch_segment(std::size_t samples);

/// The PSD of every truth and estimate trace of every axis over the hold window.
struct AxisSpectra {
  std::string axis, unit;
  std::vector<std::pair<std::string, Spectrum>> spectra;  ///< trace label -> spectrum
};
std::vector<AxisSpectra> hold_spectra(const std::vector<AxisTraces>& axes, const TimeGrid& grid,
                                      const HoldWindow& hold);

}  // namespace lode::plot
