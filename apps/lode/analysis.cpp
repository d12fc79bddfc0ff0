#include "analysis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

namespace lode::analysis {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

// ---- WindowAccumulator --------------------------------------------------------------------

WindowAccumulator::WindowAccumulator(std::size_t width, double t0, double t1)
    : t0_(t0), t1_(t1), mean_(width, 0.0), m2_(width, 0.0), sum2_(width, 0.0), max_abs_(width, 0.0) {}

void WindowAccumulator::add(double t, const double* a, const double* b) {
  if (t > t1_) closed_ = true;
  if (t < t0_ || t > t1_) return;
  ++count_;
  const double n = static_cast<double>(count_);
  for (std::size_t i = 0; i < mean_.size(); ++i) {
    const double v = a[i] - (b ? b[i] : 0.0);
    const double delta = v - mean_[i];
    mean_[i] += delta / n;
    m2_[i] += delta * (v - mean_[i]);
    sum2_[i] += v * v;
    max_abs_[i] = std::max(max_abs_[i], std::abs(v));
  }
}

std::vector<AxisStats> WindowAccumulator::result() const {
  std::vector<AxisStats> out(mean_.size());
  if (count_ == 0) return out;
  const double n = static_cast<double>(count_);
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].mean = mean_[i];
    out[i].std = count_ > 1 ? std::sqrt(m2_[i] / (n - 1.0)) : 0.0;
    out[i].rms = std::sqrt(sum2_[i] / n);
    out[i].max_abs = max_abs_[i];
    out[i].samples = count_;
  }
  return out;
}

// ---- StepResponseTracker ------------------------------------------------------------------

StepResponseTracker::StepResponseTracker(std::size_t reference_width, std::size_t response_width,
                                         double settle_band, std::size_t max_steps)
    : ref_width_(reference_width), y_width_(response_width), settle_band_(settle_band), max_steps_(max_steps) {}

void StepResponseTracker::add(double t, const double* reference, const double* response) {
  // recent_ is a ring of three samples, reused: a day-long run feeds 69 million of them.
  if (recent_.size() < 3) recent_.resize(3, Sample{0.0, std::vector<double>(ref_width_), std::vector<double>(y_width_)});
  const std::size_t slot = count_ == 0 ? 0 : (pending_ + 1) % 3;
  Sample& next = recent_[slot];
  next.t = t;
  std::copy(reference, reference + ref_width_, next.ref.begin());
  std::copy(response, response + y_width_, next.y.begin());
  // A step at sample k needs k - 1 (the jump) and k + 1 (it holds): decide k now.
  if (count_ >= 2) {
    const Sample& before = recent_[(pending_ + 2) % 3];
    const Sample& at = recent_[pending_];
    bool step = false;
    for (std::size_t i = 0; i < ref_width_ && !step; ++i)
      step = at.ref[i] - before.ref[i] != 0.0 && next.ref[i] == at.ref[i];
    if (step) {
      close_window();
      open_steps(before, at, next);
    }
    feed(at);
  }
  pending_ = slot;
  ++count_;
}

void StepResponseTracker::open_steps(const Sample& before, const Sample& at, const Sample& next) {
  for (std::size_t i = 0; i < ref_width_ && i < y_width_; ++i) {
    const double after = at.ref[i];
    if (after == before.ref[i] || next.ref[i] != after) continue;
    if (done_.size() + active_.size() >= max_steps_) {
      ++omitted_;
      continue;
    }
    Active a;
    a.s.axis = i;
    a.s.time_s = at.t;
    a.s.amplitude = after - before.ref[i];
    a.after = after;
    a.sign = a.s.amplitude > 0 ? 1.0 : -1.0;
    a.y0 = at.y[i];
    double band = settle_band_ * std::abs(a.s.amplitude);
    if (i < noise_floor_.size()) band = std::max(band, noise_floor_[i]);
    a.s.settling_band = band;
    a.s.peak_coupling.assign(y_width_, 0.0);
    a.tail.assign(kTailCapacity, 0.0);
    active_.push_back(std::move(a));
  }
}

void StepResponseTracker::track(Active& a, const Sample& sample) {
  const std::size_t i = a.s.axis;
  const double y = sample.y[i];
  const double span = a.after - a.y0;
  // The 10 % and 90 % crossings, interpolated between samples; a level already passed at the
  // step sample counts as crossed there.
  for (auto [fraction, found, when] : {std::tuple{0.1, &a.have10, &a.t10}, std::tuple{0.9, &a.have90, &a.t90}}) {
    if (*found || a.first) continue;
    const double level = a.y0 + fraction * span;
    const double before = a.sign * (a.tail[(a.tail_next + kTailCapacity - 1) % kTailCapacity] - level);
    const double now = a.sign * (y - level);
    if (before < 0 && now >= 0) {
      const double f = before / (before - now);
      *when = a.previous_t + f * (sample.t - a.previous_t);
      *found = true;
    } else if (a.samples == 1 && before >= 0) {
      *when = a.s.time_s;
      *found = true;
    }
  }
  a.peak = std::max(a.peak, a.sign * (y - a.after));
  // Settling: the sample after the last one outside the band (the step sample counts as out).
  if (a.last_sample_out) a.t_after_last_out = sample.t;
  a.last_sample_out = a.first || std::abs(y - a.after) > a.s.settling_band;
  for (std::size_t j = 0; j < y_width_; ++j)
    if (j != i && j < ref_width_)
      a.s.peak_coupling[j] = std::max(a.s.peak_coupling[j], std::abs(sample.y[j] - sample.ref[j]));
  a.tail[a.tail_next] = y;
  a.tail_next = (a.tail_next + 1) % kTailCapacity;
  ++a.samples;
  a.first = false;
  a.previous_t = sample.t;
}

void StepResponseTracker::feed(const Sample& sample) {
  for (Active& a : active_) track(a, sample);
}

void StepResponseTracker::close_window() {
  for (Active& a : active_) {
    StepResponse& s = a.s;
    const double span = a.after - a.y0;
    s.rise_time_s = a.have10 && a.have90 ? a.t90 - a.t10 : kNaN;
    s.rise_start_s = a.have10 ? a.t10 : kNaN;
    s.overshoot_pct = 100.0 * a.peak / std::abs(span);
    s.settling_time_s = a.last_sample_out ? kNaN : a.t_after_last_out - s.time_s;
    const std::size_t tail = std::min({std::max<std::size_t>(1, a.samples / 10), a.samples, kTailCapacity});
    double sum = 0.0;
    for (std::size_t k = 1; k <= tail; ++k) sum += a.tail[(a.tail_next + kTailCapacity - k) % kTailCapacity];
    s.steady_state_error = tail > 0 ? sum / static_cast<double>(tail) - a.after : kNaN;
    done_.push_back(std::move(s));
  }
  active_.clear();
}

std::vector<StepResponse> StepResponseTracker::finish() {
  // The pending sample (the last) can start no step: nothing after it holds. The first sample
  // is never fed: no step can be open before the second.
  if (count_ >= 2) feed(recent_[pending_]);
  count_ = 0;
  pending_ = 0;
  close_window();
  return std::move(done_);
}

// ---- the batch forms ----------------------------------------------------------------------

std::vector<StepResponse> step_responses(const std::vector<double>& t, const Series& ref,
                                         const Series& y, double settle_band,
                                         const std::vector<double>& noise_floor) {
  if (t.size() < 3 || ref.width() == 0) return {};
  StepResponseTracker tracker(ref.width(), y.width(), settle_band, std::numeric_limits<std::size_t>::max());
  tracker.set_noise_floor(noise_floor);
  for (std::size_t k = 0; k < t.size(); ++k)
    tracker.add(t[k], ref.values.data() + k * ref.width(), y.values.data() + k * y.width());
  return tracker.finish();
}

std::vector<AxisStats> window_stats(const std::vector<double>& t, const Series& a, const Series* b,
                                    double t0, double t1) {
  WindowAccumulator acc(a.width(), t0, t1);
  for (std::size_t k = 0; k < t.size(); ++k)
    acc.add(t[k], a.values.data() + k * a.width(), b ? b->values.data() + k * b->width() : nullptr);
  return acc.result();
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
