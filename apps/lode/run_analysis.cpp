#include "run_analysis.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <string>

namespace lode::cli {

using analysis::AxisStats;
using analysis::StepResponseTracker;
using analysis::WindowAccumulator;

namespace {

constexpr double kForever = std::numeric_limits<double>::infinity();

// fprintf that prints nothing when `out` is null (a summary computed only for its JSON).
__attribute__((format(printf, 2, 3))) void say(std::FILE* out, const char* format, ...) {
  if (!out) return;
  va_list args;
  va_start(args, format);
  std::vfprintf(out, format, args);
  va_end(args);
}

Json stats_json(const std::vector<AxisStats>& stats, const Elements& e) {
  Json j = Json::object();
  for (std::size_t i = 0; i < stats.size() && i < e.size(); ++i) {
    Json a = Json::object();
    a["unit"] = e[i].unit;
    a["std"] = stats[i].std;
    a["rms"] = stats[i].rms;
    a["mean"] = stats[i].mean;
    a["max_abs"] = stats[i].max_abs;
    a["samples"] = static_cast<std::uint64_t>(stats[i].samples);
    j[e[i].name] = std::move(a);
  }
  return j;
}

void print_stats(std::FILE* out, const char* title, const std::vector<AxisStats>& stats, const Elements& e, bool std_only) {
  say(out, "  %-34s", title);
  for (std::size_t i = 0; i < stats.size() && i < e.size(); ++i) {
    auto [scale, unit] = analysis::display_scale(e[i].unit, std_only ? stats[i].std : std::max(stats[i].rms, stats[i].max_abs));
    if (std_only)
      say(out, "  %s %.3f %s", e[i].name.c_str(), stats[i].std * scale, unit.c_str());
    else
      say(out, "  %s rms %.3f max %.3f %s", e[i].name.c_str(), stats[i].rms * scale, stats[i].max_abs * scale,
                  unit.c_str());
  }
  say(out, "\n");
}

}  // namespace

/// Every running statistic of the summary: constant memory whatever the run's length.
struct RunAnalysis::Streams {
  double h0 = 0.0, h1 = kForever;
  std::optional<WindowAccumulator> hold_truth, hold_estimate, estimation_error, tracking;
  std::vector<WindowAccumulator> extra_hold;
  std::vector<std::optional<WindowAccumulator>> extra_error;
  std::vector<bool> extra_is_estimate;
  std::optional<StepResponseTracker> steps;
  bool noise_floor_set = false;
};

RunAnalysis::RunAnalysis(const Pipeline& pipeline) : pipeline_(pipeline), streams_(std::make_unique<Streams>()) {
  // Every signal the monitor names, each tapped once.
  std::vector<SignalRef> tapped;
  auto add = [&](const std::optional<SignalRef>& s) -> int {
    if (!s) return -1;
    for (std::size_t i = 0; i < tapped.size(); ++i)
      if (tapped[i].data == s->data) return static_cast<int>(i);
    tapped.push_back(*s);
    return static_cast<int>(tapped.size() - 1);
  };
  const auto& mon = pipeline.monitor();
  show_ = add(mon.show);
  estimate_ = add(mon.estimate);
  truth_ = add(mon.truth);
  reference_ = add(mon.reference);
  for (const auto& s : mon.record) extra_.push_back(add(s));
  tap_ = std::make_unique<SignalTap>(tapped, 1 << 15);

  Streams& st = *streams_;
  if (mon.hold_end_s > mon.hold_start_s) {
    st.h0 = mon.hold_start_s;
    st.h1 = mon.hold_end_s;
  }
  const auto width = [&](int index) { return tap_->signals()[static_cast<std::size_t>(index)].size(); };
  if (truth_ < 0) return;
  st.hold_truth.emplace(width(truth_), st.h0, st.h1);
  if (estimate_ >= 0) {
    st.hold_estimate.emplace(width(estimate_), st.h0, st.h1);
    // From the start of the hold window: the start-up transient is not an estimation error.
    st.estimation_error.emplace(width(estimate_), st.h0, kForever);
  }
  // A shadow's `disagreement` (its estimate minus its primary's) and `nis` are not estimates
  // of the truth: no error against it.
  const auto shadows = pipeline.shadows();
  const auto is_estimate = [&](const SignalRef& s) {
    for (const auto& sh : shadows)
      if (sh.name == s.block && (s.port == "disagreement" || s.port == "nis")) return false;
    return true;
  };
  for (const int index : extra_) {
    st.extra_hold.emplace_back(width(index), st.h0, st.h1);
    st.extra_error.emplace_back();
    st.extra_is_estimate.push_back(is_estimate(tapped[static_cast<std::size_t>(index)]));
    if (width(index) == width(truth_) && st.extra_is_estimate.back())
      st.extra_error.back().emplace(width(index), st.h0, kForever);
  }
  if (reference_ >= 0) {
    st.tracking.emplace(width(reference_), st.h0, kForever);
    st.steps.emplace(width(reference_), width(truth_), mon.settle_band);
  }
}

RunAnalysis::~RunAnalysis() = default;

void RunAnalysis::drain() {
  scratch_.clear();
  tap_->drain(scratch_);
  const std::size_t stride = tap_->stride();
  for (std::size_t k = 0; k + stride <= scratch_.size(); k += stride) add_row(scratch_.data() + k);
  if (scratch_.size() >= stride) last_row_.assign(scratch_.end() - static_cast<std::ptrdiff_t>(stride), scratch_.end());
}

void RunAnalysis::add_row(const double* row) {
  const double t = row[1];
  if (samples_ == 0) first_t_ = t;
  last_t_ = t;
  ++samples_;
  Streams& st = *streams_;
  if (truth_ < 0) return;
  const auto at = [&](int index) { return row + tap_->column(static_cast<std::size_t>(index)); };
  const double* truth = at(truth_);
  st.hold_truth->add(t, truth);
  if (estimate_ >= 0) {
    st.hold_estimate->add(t, at(estimate_));
    st.estimation_error->add(t, at(estimate_), truth);
  }
  for (std::size_t e = 0; e < extra_.size(); ++e) {
    st.extra_hold[e].add(t, at(extra_[e]));
    if (st.extra_error[e]) st.extra_error[e]->add(t, at(extra_[e]), truth);
  }
  if (reference_ >= 0) {
    st.tracking->add(t, at(reference_), truth);
    // A settling band narrower than the noise would make the settling time a measure of the
    // last noise peak: once the hold window is over, steps get a band of at least 3 sigma of
    // its noise (steps that start inside the hold window keep the plain band).
    if (!st.noise_floor_set && st.hold_truth->closed()) {
      std::vector<double> floor;
      for (const auto& a : st.hold_truth->result()) floor.push_back(3.0 * a.std);
      st.steps->set_noise_floor(std::move(floor));
      st.noise_floor_set = true;
    }
    st.steps->add(t, at(reference_), truth);
  }
}

const SignalRef* RunAnalysis::shown() const {
  return show_ >= 0 ? &tap_->signals()[static_cast<std::size_t>(show_)] : nullptr;
}

std::vector<double> RunAnalysis::last_shown() const {
  if (show_ < 0 || last_row_.empty()) return {};
  const auto& sig = tap_->signals()[static_cast<std::size_t>(show_)];
  const double* v = last_row_.data() + tap_->column(static_cast<std::size_t>(show_));
  return {v, v + sig.size()};
}

Json RunAnalysis::finish() {
  drain();
  Json out = Json::object();
  if (samples_ < 3 || truth_ < 0) return out;
  Streams& st = *streams_;
  const auto elements = [&](int index) -> const Elements& {
    return *tap_->signals()[static_cast<std::size_t>(index)].elements;
  };
  const double h1 = std::isinf(st.h1) ? last_t_ : st.h1;
  say(out_, "\nsummary (%llu samples, %.3f s)\n", static_cast<unsigned long long>(samples_),
              last_t_ + 1.0 / pipeline_.rate_hz());
  const Elements& truth = elements(truth_);
  const auto hold_truth = st.hold_truth->result();
  Json noise = Json::object();
  noise["window_s"] = std::vector<double>{st.h0, h1};
  noise["truth"] = stats_json(hold_truth, truth);
  char title[96];
  std::snprintf(title, sizeof title, "position noise std [%.2f, %.2f] s", st.h0, h1);
  print_stats(out_, title, hold_truth, truth, true);
  if (estimate_ >= 0) {
    const auto hold = st.hold_estimate->result();
    noise["estimate"] = stats_json(hold, elements(estimate_));
    print_stats(out_, "  as the estimator reports it", hold, elements(estimate_), true);
    const auto error = st.estimation_error->result();
    out["estimation_error"] = stats_json(error, elements(estimate_));
    print_stats(out_, "estimation error (estimate-truth)", error, elements(estimate_), false);
  }
  Json others = Json::object();
  for (std::size_t e = 0; e < extra_.size(); ++e) {
    const auto& name = tap_->signals()[static_cast<std::size_t>(extra_[e])].name();
    const Elements& el = elements(extra_[e]);
    Json oj = Json::object();
    const auto hold = st.extra_hold[e].result();
    oj["hold_noise"] = stats_json(hold, el);
    const std::string label = st.extra_is_estimate[e] ? "  as " + name + " reports it" : "  " + name + " std";
    print_stats(out_, label.c_str(), hold, el, true);
    if (st.extra_error[e]) {
      const auto error = st.extra_error[e]->result();
      oj["error_vs_truth"] = stats_json(error, el);
      print_stats(out_, ("  " + name + " - truth").c_str(), error, el, false);
    }
    others[name] = std::move(oj);
  }
  if (!extra_.empty()) out["recorded"] = std::move(others);
  out["position_noise"] = std::move(noise);
  if (reference_ >= 0) {
    const auto track = st.tracking->result();
    out["tracking_error"] = stats_json(track, truth);
    print_stats(out_, "tracking error (reference-truth)", track, truth, false);
    const auto steps = st.steps->finish();
    Json sj = Json::array();
    for (const auto& s : steps) {
      const auto& el = truth[s.axis];
      auto [scale, unit] = analysis::display_scale(el.unit, s.amplitude);
      Json j = Json::object();
      j["axis"] = el.name;
      j["time_s"] = s.time_s;
      j["amplitude"] = s.amplitude;
      j["rise_time_s"] = s.rise_time_s;
      j["rise_start_s"] = s.rise_start_s;
      j["overshoot_pct"] = s.overshoot_pct;
      j["settling_time_s"] = s.settling_time_s;
      j["settling_band"] = s.settling_band;
      j["steady_state_error"] = s.steady_state_error;
      Json coupling = Json::object();
      for (std::size_t i = 0; i < s.peak_coupling.size(); ++i)
        if (i != s.axis) coupling[truth[i].name] = s.peak_coupling[i];
      j["peak_coupling"] = std::move(coupling);
      // A step that never reached 90 % or never settled has no such time (NaN): say so in words,
      // as the report does.
      const auto milliseconds = [](double seconds, const char* never) {
        char text[32];
        if (std::isfinite(seconds)) std::snprintf(text, sizeof text, "%.1f ms", seconds * 1e3);
        else std::snprintf(text, sizeof text, "%s", never);
        return std::string(text);
      };
      say(out_, "  step %-8s at %.3f s of %+.1f %s: rise %s, overshoot %.1f %%, settling (+-%.2f %s) %s, "
                  "steady-state error %+.3f %s\n",
                  el.name.c_str(), s.time_s, s.amplitude * scale, unit.c_str(),
                  milliseconds(s.rise_time_s, "never (did not reach 90 %)").c_str(), s.overshoot_pct,
                  s.settling_band * scale, unit.c_str(), milliseconds(s.settling_time_s, "never").c_str(),
                  s.steady_state_error * scale, unit.c_str());
      sj.push(std::move(j));
    }
    out["steps"] = std::move(sj);
    if (st.steps->omitted() > 0) {
      out["steps_omitted"] = static_cast<std::uint64_t>(st.steps->omitted());
      say(out_, "  (%llu further steps not analysed: the summary keeps the first 1000)\n",
                  static_cast<unsigned long long>(st.steps->omitted()));
    }
  }
  return out;
}

}  // namespace lode::cli
