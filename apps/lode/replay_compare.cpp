// What a replay is judged by: the recorded configuration bit for bit against the recording,
// and every estimator's error, noise, NIS consistency and step time.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <set>

#include "lode/sdk/math/statistics.hpp"
#include "replay.hpp"

namespace lode::cli {

namespace {

/// Recorded series `a` against replayed `b` (same name): "" when bit-identical, else the first
/// difference.
std::string first_difference(const record::SeriesData& a, const record::SeriesData& b) {
  if (a.width() != b.width() || a.info.names != b.info.names) return "series " + a.info.name + ": different elements";
  if (a.rows() != b.rows())
    return "series " + a.info.name + ": " + std::to_string(a.rows()) + " cycles recorded, " +
           std::to_string(b.rows()) + " replayed";
  for (std::size_t k = 0; k < a.rows(); ++k) {
    if (a.cycle[k] != b.cycle[k])
      return "series " + a.info.name + ": row " + std::to_string(k) + " is cycle " + std::to_string(a.cycle[k]) +
             " recorded, " + std::to_string(b.cycle[k]) + " replayed";
    const double* va = a.values.data() + k * a.width();
    const double* vb = b.values.data() + k * b.width();
    if (std::memcmp(va, vb, a.width() * sizeof(double)) == 0) continue;
    for (std::size_t i = 0; i < a.width(); ++i) {
      if (std::memcmp(va + i, vb + i, sizeof(double)) == 0) continue;
      char buf[320];
      std::snprintf(buf, sizeof buf, "series %s, cycle %llu, element %s: recorded %.17g, replayed %.17g",
                    a.info.name.c_str(), static_cast<unsigned long long>(a.cycle[k]), a.info.names[i].c_str(), va[i],
                    vb[i]);
      return buf;
    }
  }
  return "";
}

/// The largest difference of two series of one shape ("" when none differ or the shapes do:
/// the first difference names that).
std::string largest_difference(const record::SeriesData& a, const record::SeriesData& b) {
  if (a.width() != b.width() || a.rows() != b.rows()) return "";
  const std::size_t width = a.width();
  // Each element's scale: its largest recorded magnitude (an element that crosses zero,
  // such as a velocity, has no meaningful element-by-element relative difference there).
  std::vector<double> scale(width, 0.0);
  for (std::size_t k = 0; k < a.rows(); ++k)
    for (std::size_t i = 0; i < width; ++i) scale[i] = std::max(scale[i], std::abs(a.values[k * width + i]));
  double worst = 0.0;
  std::size_t worst_row = 0, worst_element = 0;
  bool differs = false;
  for (std::size_t k = 0; k < a.rows(); ++k) {
    for (std::size_t i = 0; i < width; ++i) {
      const double x = a.values[k * width + i], y = b.values[k * width + i];
      if (std::memcmp(&x, &y, sizeof x) == 0) continue;
      const double relative = scale[i] > 0.0 ? std::abs(x - y) / scale[i] : std::abs(x - y);
      // NaN against a number, or a different NaN: as large as a difference gets.
      const double d = std::isnan(relative) ? std::numeric_limits<double>::infinity() : relative;
      if (!differs || d > worst) {
        worst = d;
        worst_row = k;
        worst_element = i;
      }
      differs = true;
    }
  }
  if (!differs) return "";
  char buf[320];
  std::snprintf(buf, sizeof buf, "largest relative difference %.2g in %s.%s at cycle %llu", worst, a.info.name.c_str(),
                a.info.names[worst_element].c_str(), static_cast<unsigned long long>(a.cycle[worst_row]));
  return buf;
}

}  // namespace

Expected<BitCompare> compare_recording_files(const std::string& recorded, const std::string& replayed) {
  auto recorded_file = record::SeriesReader::open(recorded);
  if (!recorded_file) return recorded_file.status();
  auto replayed_file = record::SeriesReader::open(replayed);
  if (!replayed_file) return replayed_file.status();
  const auto& replayed_names = (*replayed_file)->names();
  const std::set<std::string> in_replay(replayed_names.begin(), replayed_names.end());
  BitCompare r;
  std::set<std::string> seen;
  std::vector<std::string> warnings;  // said when the recording itself was read
  for (const auto& name : (*recorded_file)->names()) {
    if (!in_replay.count(name)) {
      r.only_in_one.push_back(name + " (only in the recording)");
      continue;
    }
    seen.insert(name);
    auto a = (*recorded_file)->read(name, warnings);
    if (!a) return a.status();
    auto b = (*replayed_file)->read(name, warnings);
    if (!b) return b.status();
    ++r.series;
    r.cycles = std::max(r.cycles, a->rows());
    const std::string difference = first_difference(*a, *b);
    if (difference.empty()) continue;
    if (r.first_difference.empty()) r.first_difference = difference;
    if (std::string line = largest_difference(*a, *b); !line.empty()) r.largest_differences.push_back(std::move(line));
  }
  for (const auto& name : replayed_names)
    if (!seen.count(name)) r.only_in_one.push_back(name + " (only in the replay)");
  return r;
}

void estimator_statistics(const CompareHook& hook, const Pipeline& pipeline, int reference_index,
                          std::vector<EstimatorStats>& estimators, std::vector<std::string>& notes) {
  using analysis::window_stats;
  const auto t = hook.time_s();
  const auto& mon = pipeline.monitor();
  double h0 = mon.hold_start_s, h1 = mon.hold_end_s;
  if (h1 <= h0) {
    h0 = 0.0;
    h1 = t.empty() ? 0.0 : t.back();
  }
  const double t_end = t.empty() ? 0.0 : t.back();
  std::optional<analysis::Series> ref_series;
  if (reference_index >= 0) ref_series = hook.series(static_cast<std::size_t>(reference_index));
  for (std::size_t i = 0; i < estimators.size(); ++i) {
    auto& e = estimators[i];
    const auto est = hook.series(i);
    // The reference's element matching each estimate element: by name, else by position.
    std::vector<int> match(est.width(), -1);
    if (ref_series) {
      for (std::size_t k = 0; k < est.width(); ++k)
        for (std::size_t r = 0; r < ref_series->width(); ++r)
          if (ref_series->elements[r].name == est.elements[k].name) match[k] = static_cast<int>(r);
      if (std::all_of(match.begin(), match.end(), [](int m) { return m < 0; }) && est.width() == ref_series->width())
        for (std::size_t k = 0; k < est.width(); ++k) match[k] = static_cast<int>(k);
    }
    analysis::Series aligned;
    aligned.elements = est.elements;
    aligned.values.assign(est.values.size(), 0.0);
    if (ref_series)
      for (std::size_t r = 0; r < t.size(); ++r)
        for (std::size_t k = 0; k < est.width(); ++k)
          aligned.values[r * est.width() + k] =
              match[k] >= 0 ? ref_series->at(r, static_cast<std::size_t>(match[k])) : std::nan("");
    const auto err = ref_series ? window_stats(t, est, &aligned, h0, t_end) : std::vector<analysis::AxisStats>{};
    const auto hold = window_stats(t, est, ref_series ? &aligned : nullptr, h0, h1);
    for (std::size_t k = 0; k < est.width(); ++k) {
      EstimatorStats::Element el;
      el.name = est.elements[k].name;
      el.unit = est.elements[k].unit;
      if (ref_series && match[k] >= 0) {
        el.bias = err[k].mean;
        el.rms = err[k].rms;
        el.max_abs = err[k].max_abs;
        el.noise_std = hold[k].std;
      } else if (!ref_series) {
        el.noise_std = hold[k].std;  // the estimate's own scatter in the hold window
      }
      e.elements.push_back(el);
    }
    if (const auto* n = hook.nis(e.block); n && !n->nu.empty()) {
      e.nis_channels = n->nu.size();
      const double m = static_cast<double>(e.nis_channels);
      e.nis_lo = math::chi_square_quantile(0.025, m);
      e.nis_hi = math::chi_square_quantile(0.975, m);
      double sum = 0.0;
      std::size_t inside = 0;
      for (std::size_t k = 0; k < hook.rows(); ++k) {
        const double v = n->values[k];
        if (!std::isfinite(v)) continue;
        ++e.nis_cycles;
        sum += v;
        if (v >= e.nis_lo && v <= e.nis_hi) ++inside;
      }
      if (e.nis_cycles > 0) {
        e.nis_mean = sum / static_cast<double>(e.nis_cycles);
        e.nis_in_95 = static_cast<double>(inside) / static_cast<double>(e.nis_cycles);
      }
    }
    for (const auto& op : pipeline.ops())
      if (op.label == e.block && op.exec_time && op.exec_time->count() > 0)
        e.median_step_us = static_cast<double>(op.exec_time->percentile(0.5)) * 1e-3;
    if (!std::isfinite(e.median_step_us) && e.role.rfind("shadow", 0) == 0)
      notes.push_back("shadow " + e.block + " is stepped inside its primary's operation: no step time of its own");
  }
}

}  // namespace lode::cli
