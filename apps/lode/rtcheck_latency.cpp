#include "rtcheck_latency.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <thread>

#include "cli.hpp"
#include "cycle_cost.hpp"
#include "lode/realtime.hpp"

namespace lode::cli {

namespace {
constexpr std::int64_t kMaxDurationNs = 24LL * 3600 * 1'000'000'000;

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

double us(std::int64_t ns) { return static_cast<double>(ns) / 1000.0; }

/// The loop cyclictest runs: sleep to an absolute deadline, read the clock, record how late.
/// A wake-up later than the next deadline skips the deadlines already passed, as cyclictest
/// and `lode run` (overrun_policy: skip) do: they are counted, not recorded as a burst of
/// late catch-up wake-ups. Nothing here allocates or locks; the histogram is fixed storage.
void wakeup_loop(const LatencyPlan& plan, LatencyReport& report) {
  std::int64_t next = now_ns() + plan.period_ns;
  const std::int64_t end = next + plan.duration_ns;
  while (next < end) {
    if (stop_requested().load(std::memory_order_relaxed)) {
      report.interrupted = true;
      return;
    }
    timespec ts{static_cast<time_t>(next / 1'000'000'000), static_cast<long>(next % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const std::int64_t woke = now_ns();
    report.wakeups->record(woke - next);
    next += plan.period_ns;
    if (woke > next) {
      const std::int64_t missed = (woke - next) / plan.period_ns + 1;
      // Only the deadlines inside the measured window count (count + missed = window / period).
      const std::int64_t in_window = next < end ? std::min(missed, (end - next + plan.period_ns - 1) / plan.period_ns) : 0;
      next += missed * plan.period_ns;
      report.missed_periods += static_cast<std::uint64_t>(in_window);
    }
  }
}

/// The display bins of the text histogram, in microseconds (upper edges).
constexpr double kEdgesUs[] = {1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 1e18};
constexpr std::size_t kDisplayBins = std::size(kEdgesUs);

std::array<std::uint64_t, kDisplayBins> display_bins(const Histogram& h) {
  std::array<std::uint64_t, kDisplayBins> counts{};
  h.for_each_bin([&](std::int64_t upper_ns, std::uint64_t n) {
    std::size_t i = 0;
    while (i + 1 < kDisplayBins && us(upper_ns) > kEdgesUs[i]) ++i;
    counts[i] += n;
  });
  return counts;
}

std::string edge_label(std::size_t i) {
  char buf[48];
  if (i + 1 == kDisplayBins)
    std::snprintf(buf, sizeof buf, ">%g us", kEdgesUs[i - 1]);
  else
    std::snprintf(buf, sizeof buf, "%g-%g us", i == 0 ? 0.0 : kEdgesUs[i - 1], kEdgesUs[i]);
  return buf;
}
}  // namespace

std::optional<std::int64_t> parse_duration_ns(const std::string& text, std::string& why) {
  why = "'" + text + "' is not a duration: write 10s, 500ms, 2m, 8h or a number of seconds";
  std::size_t digits = 0;
  while (digits < text.size() && (std::isdigit(static_cast<unsigned char>(text[digits])) || text[digits] == '.')) ++digits;
  const std::string number = text.substr(0, digits), unit = text.substr(digits);
  double value = 0;
  const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (number.empty() || ec != std::errc() || end != number.data() + number.size()) return std::nullopt;
  double scale = 0;
  if (unit.empty() || unit == "s") scale = 1e9;
  else if (unit == "ms") scale = 1e6;
  else if (unit == "m") scale = 60e9;
  else if (unit == "h") scale = 3600e9;  // an overnight soak is the usual way to find the rare latency
  else return std::nullopt;
  const double ns = value * scale;
  if (!std::isfinite(ns) || ns < 1e6 || ns > static_cast<double>(kMaxDurationNs)) {
    why = "'" + text + "' is outside 1ms..24h";
    return std::nullopt;
  }
  why.clear();
  return static_cast<std::int64_t>(ns);
}

std::int64_t LatencyReport::headroom_ns() const {
  const std::int64_t cost = cycle_cost && cycle_cost->count() ? cycle_cost->percentile(0.99) : 0;
  return plan.period_ns - (wakeups->max() + cost);
}

LatencyReport measure_latency(const LatencyPlan& plan) {
  LatencyReport report;
  report.plan = plan;
  RealtimeSettings settings;
  settings.priority = plan.priority;
  settings.cpu = plan.cpu;
  settings.lock_memory = true;  // as cyclictest -m: no page fault inside the loop
  report.setup_warnings = apply_process_realtime(settings);
  if (plan.pipeline) report.cycle_cost = std::make_unique<Histogram>();
  std::thread measuring([&] {
    for (auto& w : apply_thread_realtime(settings)) report.setup_warnings.push_back(std::move(w));
    int policy = 0;
    sched_param sp{};
    pthread_getschedparam(pthread_self(), &policy, &sp);
    report.sched_fifo = plan.priority > 0 && policy == SCHED_FIFO && sp.sched_priority == plan.priority;
    cpu_set_t set;
    CPU_ZERO(&set);
    report.pinned = plan.cpu >= 0 && pthread_getaffinity_np(pthread_self(), sizeof set, &set) == 0 &&
                    CPU_COUNT(&set) == 1 && CPU_ISSET(plan.cpu, &set);
    // The cycle's cost on the same CPU and priority the loop will have.
    if (plan.pipeline) report.cycle_cost_error = run_cycles_timed(*plan.pipeline, plan.cost_cycles, *report.cycle_cost);
    wakeup_loop(plan, report);
  });
  measuring.join();
  release_process_realtime();
  return report;
}

std::vector<CheckResult> latency_checks(const LatencyReport& r) {
  std::vector<CheckResult> checks;
  CheckResult setup{"latency_setup", CheckStatus::pass, "", ""};
  std::string how = r.sched_fifo ? "SCHED_FIFO " + std::to_string(r.plan.priority) : "normal scheduling";
  how += r.pinned ? ", CPU " + std::to_string(r.plan.cpu) : ", any CPU";
  setup.found = "measured with " + how + ", memory locked";
  const bool wanted_fifo = r.plan.priority > 0, wanted_cpu = r.plan.cpu >= 0;
  if ((wanted_fifo && !r.sched_fifo) || (wanted_cpu && !r.pinned) || !r.setup_warnings.empty()) {
    // The figures are still measured, but not under the pipeline's conditions.
    setup.status = CheckStatus::warn;
    setup.found = "measured with " + how + " (not what the pipeline asks):";
    for (const auto& w : r.setup_warnings) setup.found += " " + w + ";";
    setup.fix = "fix the rtprio/memlock/isolated_cpus findings above, then measure again";
  }
  checks.push_back(std::move(setup));

  CheckResult head{"headroom", CheckStatus::pass, "", ""};
  const auto headroom = r.headroom_ns();
  const bool with_cost = r.cycle_cost && r.cycle_cost->count();
  char buf[256];
  std::snprintf(buf, sizeof buf, "%.1f us of the %.1f us period left after the worst wake-up (%.1f us)%s",
                us(headroom), us(r.plan.period_ns), us(r.wakeups->max()),
                with_cost ? " and the cycle's p99 cost" : " (no pipeline: cycle cost not included)");
  head.found = buf;
  if (r.wakeups->count() == 0) {
    head.status = CheckStatus::warn;
    head.found = "no wake-up measured";
    head.fix = "measure for longer: --latency 10s";
  } else if (headroom < 0) {
    // The worst wake-up plus a p99 cycle does not fit the period: the loop overruns.
    head.status = CheckStatus::fail;
    head.fix = "make the host quieter (the WARN findings above), or lower rate_hz";
  } else if (headroom * 10 < r.plan.period_ns) {
    head.status = CheckStatus::warn;
    head.fix = "less than 10 % of the period is left: make the host quieter (the WARN findings above), or lower rate_hz";
  }
  if (!r.plan.cycle_cost_skipped.empty()) {
    head.status = std::max(head.status, CheckStatus::warn);
    head.found += "; the pipeline's cycle was not timed: " + r.plan.cycle_cost_skipped;
    if (head.fix.empty()) head.fix = "run `lode bench` on the pipeline's simulation twin and subtract its p99 from the headroom";
  }
  if (!r.cycle_cost_error.empty()) {
    head.status = std::max(head.status, CheckStatus::warn);
    head.found += "; the pipeline's cycle could not be timed: " + r.cycle_cost_error;
    if (head.fix.empty()) head.fix = "run `lode bench CONFIG` to see the cycle's cost";
  }
  checks.push_back(std::move(head));
  return checks;
}

Json latency_json(const LatencyReport& r) {
  const auto& h = *r.wakeups;
  Json j = Json::object();
  j["cpu"] = r.plan.cpu;
  j["priority"] = r.plan.priority;
  j["sched_fifo"] = r.sched_fifo;
  j["pinned"] = r.pinned;
  j["period_us"] = us(r.plan.period_ns);
  j["duration_s"] = static_cast<double>(r.plan.duration_ns) / 1e9;
  j["interrupted"] = r.interrupted;
  j["count"] = h.count();
  j["missed_periods"] = r.missed_periods;
  j["min_us"] = us(h.count() ? h.min() : 0);
  j["p50_us"] = us(h.percentile(0.5));
  j["p90_us"] = us(h.percentile(0.9));
  j["p99_us"] = us(h.percentile(0.99));
  j["p999_us"] = us(h.percentile(0.999));
  j["max_us"] = us(h.max());
  Json bins = Json::array();
  const auto counts = display_bins(h);
  for (std::size_t i = 0; i < kDisplayBins; ++i) {
    Json b = Json::object();
    b["up_to_us"] = i + 1 == kDisplayBins ? Json(nullptr) : Json(kEdgesUs[i]);
    b["count"] = counts[i];
    bins.push(std::move(b));
  }
  j["histogram"] = std::move(bins);
  if (r.cycle_cost && r.cycle_cost->count()) {
    j["cycle_cost_p99_us"] = us(r.cycle_cost->percentile(0.99));
    j["cycle_cost_cycles"] = r.cycle_cost->count();
  } else {
    j["cycle_cost_p99_us"] = nullptr;
  }
  j["headroom_us"] = us(r.headroom_ns());
  return j;
}

std::string latency_text(const LatencyReport& r) {
  const auto& h = *r.wakeups;
  std::string out;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "wake-up latency: %llu wake-ups every %.1f us (%llu periods missed)%s, %s, %s\n"
                "  min %.1f  p50 %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f   (us)\n",
                static_cast<unsigned long long>(h.count()), us(r.plan.period_ns),
                static_cast<unsigned long long>(r.missed_periods), r.interrupted ? " (interrupted)" : "",
                r.sched_fifo ? ("SCHED_FIFO " + std::to_string(r.plan.priority)).c_str() : "normal scheduling",
                r.pinned ? ("CPU " + std::to_string(r.plan.cpu)).c_str() : "any CPU", us(h.count() ? h.min() : 0),
                us(h.percentile(0.5)), us(h.percentile(0.9)), us(h.percentile(0.99)), us(h.percentile(0.999)),
                us(h.max()));
  out += buf;
  const auto counts = display_bins(h);
  std::uint64_t biggest = 1;
  for (const auto c : counts) biggest = std::max(biggest, c);
  std::size_t first = kDisplayBins, last = 0;
  for (std::size_t i = 0; i < kDisplayBins; ++i)
    if (counts[i]) {
      first = std::min(first, i);
      last = i;
    }
  for (std::size_t i = first; i <= last; ++i) {
    // Log-scaled bars: the rare late wake-ups are what matters and must stay visible.
    const int bar = counts[i] ? 1 + static_cast<int>(39.0 * std::log10(static_cast<double>(counts[i])) /
                                                     std::max(1.0, std::log10(static_cast<double>(biggest))))
                              : 0;
    std::snprintf(buf, sizeof buf, "  %-14s %10llu %s\n", edge_label(i).c_str(),
                  static_cast<unsigned long long>(counts[i]), std::string(static_cast<std::size_t>(bar), '#').c_str());
    out += buf;
  }
  if (r.cycle_cost && r.cycle_cost->count())
    std::snprintf(buf, sizeof buf, "cycle cost (p99 of %llu cycles, as lode bench): %.1f us\n",
                  static_cast<unsigned long long>(r.cycle_cost->count()), us(r.cycle_cost->percentile(0.99)));
  else
    std::snprintf(buf, sizeof buf, "cycle cost: not measured (%s)\n",
                  !r.plan.cycle_cost_skipped.empty() ? r.plan.cycle_cost_skipped.c_str()
                  : r.plan.pipeline                  ? r.cycle_cost_error.c_str()
                                                     : "no pipeline");
  out += buf;
  std::snprintf(buf, sizeof buf, "headroom: period %.1f - (worst wake-up %.1f + cycle p99) = %.1f us\n",
                us(r.plan.period_ns), us(h.max()), us(r.headroom_ns()));
  out += buf;
  return out;
}

}  // namespace lode::cli
