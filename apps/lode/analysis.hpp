// End-of-run analysis for `lode run`: position noise, step responses, tracking, timing.
//
// Works on the records a SignalTap collected (one row per cycle). Pure functions of the
// recorded data, so the tests check them on synthetic signals.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lode/sdk/json.hpp"
#include "lode/sdk/port.hpp"

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
  double rise_start_s = 0.0; ///< when the response crossed 10 % (so a plot can mark the rise); NaN if never
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

// ---- one sample at a time -----------------------------------------------------------------
// `lode run` analyses runs of any length: it cannot keep every sample (a day at 800 Hz is 69
// million rows), so it feeds each drained row to these, whose memory does not grow with the
// run. The batch functions above are built on them, so both give the same figures.

/// window_stats() one sample at a time: Welford's running mean and variance, rms, max |.|.
class WindowAccumulator {
 public:
  WindowAccumulator(std::size_t width, double t0, double t1);
  /// Sample at time t: values a (and b, subtracted, unless null), `width` each.
  void add(double t, const double* a, const double* b = nullptr);
  [[nodiscard]] std::vector<AxisStats> result() const;
  /// True once a sample later than the window's end was seen: result() is final.
  [[nodiscard]] bool closed() const { return closed_; }

 private:
  double t0_, t1_;
  bool closed_ = false;
  std::vector<double> mean_, m2_, sum2_, max_abs_;
  std::size_t count_ = 0;
};

/// step_responses() one sample at a time. A step is a jump of some reference element that
/// holds for the next sample, so each sample is processed one sample late. Each step's
/// window lasts until the next step (or the end); its steady-state error is the mean over the
/// last 10 % of the window, at most the last kTailCapacity samples. At most `max_steps`
/// responses are kept; later ones are counted in omitted().
class StepResponseTracker {
 public:
  static constexpr std::size_t kTailCapacity = 16384;
  StepResponseTracker(std::size_t reference_width, std::size_t response_width, double settle_band,
                      std::size_t max_steps = 1000);
  /// Widens each axis's settling band to noise_floor[axis] for steps that start afterwards.
  void set_noise_floor(std::vector<double> noise_floor) { noise_floor_ = std::move(noise_floor); }
  void add(double t, const double* reference, const double* response);
  /// Closes the last window and returns every kept step, in order.
  std::vector<StepResponse> finish();
  [[nodiscard]] std::size_t omitted() const { return omitted_; }

 private:
  struct Sample {
    double t = 0.0;
    std::vector<double> ref, y;
  };
  struct Active {
    StepResponse s;
    double after = 0.0, y0 = 0.0, sign = 1.0, t10 = 0.0, t90 = 0.0, peak = 0.0;
    bool have10 = false, have90 = false, first = true;
    double previous_t = 0.0, t_after_last_out = 0.0;
    bool last_sample_out = false;
    std::vector<double> tail;  ///< ring of the axis's recent values
    std::size_t tail_next = 0, samples = 0;
  };
  void open_steps(const Sample& before, const Sample& at, const Sample& next);
  void feed(const Sample& sample);
  void close_window();
  void track(Active& a, const Sample& sample);

  std::size_t ref_width_, y_width_;
  double settle_band_;
  std::size_t max_steps_;
  std::vector<double> noise_floor_;
  std::vector<Sample> recent_;  ///< ring of 3: the sample before, the pending one, the newest
  std::size_t pending_ = 0;     ///< index in recent_ of the sample not yet fed
  std::size_t count_ = 0;       ///< samples added
  std::vector<Active> active_;
  std::vector<StepResponse> done_;
  std::size_t omitted_ = 0;
};

/// Human scale for a value of this magnitude in this unit: an SI prefix (n, u, m) on the
/// unit's leading symbol, e.g. (1.5e-9, "m") -> (1e9, "nm"), (2e-6, "m/s") -> (1e6, "um/s").
/// Units that do not start with m, rad or V are left alone.
std::pair<double, std::string> display_scale(const std::string& unit, double magnitude);

}  // namespace lode::analysis
