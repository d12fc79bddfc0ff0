// End-of-run analysis for `lode run`: position noise, step responses, tracking, timing.
//
// Works on the records a SignalTap collected (one row per cycle). Pure functions of the
// recorded data, so the tests check them on synthetic signals.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lode/json.hpp"
#include "lode/port.hpp"

namespace lode::analysis {

/// One recorded signal as columns: values[k * n + i] is element i at sample k.
struct Series {
  Elements elements;
  std::vector<double> values;
  [[nodiscard]] std::size_t width() const { return elements.size(); }
  [[nodiscard]] double at(std::size_t k, std::size_t i) const { return values[k * width() + i]; }
};

struct StepResponse {
  std::size_t axis = 0;
  double time_s = 0.0;       ///< when the reference stepped
  double amplitude = 0.0;    ///< reference after - before
  double rise_time_s = 0.0;  ///< 10 % -> 90 % of the step, interpolated; NaN if never reached
  double overshoot_pct = 0.0;
  double settling_time_s = 0.0;  ///< last entry into the band around the final reference; NaN if never
  double settling_band = 0.0;    ///< half-width of that band, in the axis unit
  double steady_state_error = 0.0;  ///< mean over the last 10 % of the window minus reference
  std::vector<double> peak_coupling;  ///< max |deviation| of every other axis in the window
};

/// Steps of `reference` (jumps held for at least two samples) and the response of `response`.
/// The settling band is settle_band * |step|, widened per axis to `noise_floor[axis]` if given.
std::vector<StepResponse> step_responses(const std::vector<double>& time_s, const Series& reference,
                                         const Series& response, double settle_band,
                                         const std::vector<double>& noise_floor = {});

struct AxisStats {
  double mean = 0.0;
  double std = 0.0;
  double rms = 0.0;
  double max_abs = 0.0;
  std::size_t samples = 0;
};

/// Statistics of a - b (or of a alone when b is null) per element over [t0, t1].
std::vector<AxisStats> window_stats(const std::vector<double>& time_s, const Series& a,
                                    const Series* b, double t0, double t1);

/// Human scale for a value of this magnitude in this unit: an SI prefix (n, u, m) on the
/// unit's leading symbol, e.g. (1.5e-9, "m") -> (1e9, "nm"), (2e-6, "m/s") -> (1e6, "um/s").
/// Units that do not start with m, rad or V are left alone.
std::pair<double, std::string> display_scale(const std::string& unit, double magnitude);

}  // namespace lode::analysis
