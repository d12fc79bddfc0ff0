#include "analysis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lode::analysis {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Time at which y crosses `level` going in direction `sign`, interpolated, from index k0.
double crossing_time(const std::vector<double>& t, const Series& y, std::size_t axis,
                     std::size_t k0, std::size_t k1, double level, double sign) {
  for (std::size_t k = k0 + 1; k < k1; ++k) {
    const double a = sign * (y.at(k - 1, axis) - level);
    const double b = sign * (y.at(k, axis) - level);
    if (a < 0 && b >= 0) {
      const double f = a / (a - b);
      return t[k - 1] + f * (t[k] - t[k - 1]);
    }
    if (k == k0 + 1 && a >= 0) return t[k0];
  }
  return kNaN;
}
}  // namespace

std::vector<StepResponse> step_responses(const std::vector<double>& t, const Series& ref,
                                         const Series& y, double settle_band,
                                         const std::vector<double>& noise_floor) {
  std::vector<StepResponse> out;
  const std::size_t n = t.size();
  if (n < 3 || ref.width() == 0) return out;
  // Every sample where some axis of the reference jumps and then holds.
  std::vector<std::size_t> events;
  for (std::size_t k = 1; k + 1 < n; ++k)
    for (std::size_t i = 0; i < ref.width(); ++i) {
      const double d = ref.at(k, i) - ref.at(k - 1, i);
      if (d != 0.0 && ref.at(k + 1, i) == ref.at(k, i)) {
        events.push_back(k);
        break;
      }
    }
  for (std::size_t e = 0; e < events.size(); ++e) {
    const std::size_t k0 = events[e];
    const std::size_t k1 = e + 1 < events.size() ? events[e + 1] : n;
    for (std::size_t i = 0; i < ref.width(); ++i) {
      const double before = ref.at(k0 - 1, i);
      const double after = ref.at(k0, i);
      if (after == before || ref.at(k0 + 1, i) != after) continue;
      StepResponse s;
      s.axis = i;
      s.time_s = t[k0];
      s.amplitude = after - before;
      const double sign = s.amplitude > 0 ? 1.0 : -1.0;
      const double y0 = y.at(k0, i);
      const double span = after - y0;
      const double t10 = crossing_time(t, y, i, k0, k1, y0 + 0.1 * span, sign);
      const double t90 = crossing_time(t, y, i, k0, k1, y0 + 0.9 * span, sign);
      s.rise_time_s = std::isnan(t10) || std::isnan(t90) ? kNaN : t90 - t10;
      double peak = 0.0;
      for (std::size_t k = k0; k < k1; ++k) peak = std::max(peak, sign * (y.at(k, i) - after));
      s.overshoot_pct = 100.0 * peak / std::abs(span);
      double band = settle_band * std::abs(s.amplitude);
      if (i < noise_floor.size()) band = std::max(band, noise_floor[i]);
      s.settling_band = band;
      std::size_t last_out = k0;
      for (std::size_t k = k0; k < k1; ++k)
        if (std::abs(y.at(k, i) - after) > band) last_out = k;
      s.settling_time_s = last_out + 1 < k1 ? t[last_out + 1] - t[k0] : kNaN;
      const std::size_t tail = std::max<std::size_t>(1, (k1 - k0) / 10);
      double sum = 0.0;
      for (std::size_t k = k1 - tail; k < k1; ++k) sum += y.at(k, i);
      s.steady_state_error = sum / static_cast<double>(tail) - after;
      for (std::size_t j = 0; j < y.width(); ++j) {
        double c = 0.0;
        if (j != i)
          for (std::size_t k = k0; k < k1; ++k)
            c = std::max(c, std::abs(y.at(k, j) - ref.at(k, j)));
        s.peak_coupling.push_back(c);
      }
      out.push_back(std::move(s));
    }
  }
  return out;
}

std::vector<AxisStats> window_stats(const std::vector<double>& t, const Series& a, const Series* b,
                                    double t0, double t1) {
  std::vector<AxisStats> out(a.width());
  for (std::size_t i = 0; i < a.width(); ++i) {
    double sum = 0.0, sum2 = 0.0, max_abs = 0.0;
    std::size_t m = 0;
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (t[k] < t0 || t[k] > t1) continue;
      const double v = a.at(k, i) - (b ? b->at(k, i) : 0.0);
      sum += v;
      sum2 += v * v;
      max_abs = std::max(max_abs, std::abs(v));
      ++m;
    }
    if (m == 0) continue;
    const double mean = sum / static_cast<double>(m);
    double var = 0.0;
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (t[k] < t0 || t[k] > t1) continue;
      const double v = a.at(k, i) - (b ? b->at(k, i) : 0.0) - mean;
      var += v * v;
    }
    out[i].mean = mean;
    out[i].std = m > 1 ? std::sqrt(var / static_cast<double>(m - 1)) : 0.0;
    out[i].rms = std::sqrt(sum2 / static_cast<double>(m));
    out[i].max_abs = max_abs;
    out[i].samples = m;
  }
  return out;
}

std::pair<double, std::string> display_scale(const std::string& unit, double magnitude) {
  const bool scalable = unit == "m" || unit.rfind("m/", 0) == 0 || unit.rfind("rad", 0) == 0 ||
                        unit == "V" || unit.rfind("V/", 0) == 0;
  if (!scalable) return {1.0, unit};
  const double m = std::abs(magnitude);
  if (m == 0.0 || !std::isfinite(m)) return {1e6, "u" + unit};
  if (m < 1e-6) return {1e9, "n" + unit};
  if (m < 1e-3) return {1e6, "u" + unit};
  if (m < 1.0) return {1e3, "m" + unit};
  return {1.0, unit};
}

}  // namespace lode::analysis
