// The health monitor of a primary estimator (`health:`): non-finite outputs, the exported
// covariance's Cholesky factorisation, the windowed NIS against a chi-square threshold and the
// step time against its budget; a trip hands over to the fallback shadow in the same cycle.
#include "lode/sdk/clock.hpp"
#include "lode/config_file.hpp"
#include "lode/sdk/math/statistics.hpp"
#include "lode/pipeline.hpp"

#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstring>
#include <fstream>
#include <limits>
#include <deque>
#include <map>
#include <set>
#include <sstream>

#include "lode/telemetry.hpp"
#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

void Pipeline::Impl::push_trip(const TripRecord& t) noexcept {
  trips.push(t);  // full: dropped and counted, reported by take_health_trips()
}

namespace {
/// In-place Cholesky test of a symmetric n x n row-major matrix (destroys `a`). True when
/// positive definite. No allocation: the health monitor runs it on the RT thread.
bool positive_definite(double* a, std::size_t n) noexcept {
  for (std::size_t j = 0; j < n; ++j) {
    double d = a[j * n + j];
    for (std::size_t k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double l = std::sqrt(d);
    a[j * n + j] = l;
    for (std::size_t i = j + 1; i < n; ++i) {
      double v = a[i * n + j];
      for (std::size_t k = 0; k < j; ++k) v -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = v / l;
    }
  }
  return true;
}
}  // namespace

StepStatus Pipeline::Impl::after_primary(Family& f, const Tick& tick, StepStatus status, std::int64_t step_ns,
                                         const char*& reason) noexcept {
  // Shadows run on the inputs the primary just used; their faults are counted, never fatal.
  for (auto& slot : f.shadows) {
    slot.stepped_ok = false;
    if (slot.decimation > 1 && tick.cycle % slot.decimation != 0) continue;
    Tick t = tick;
    t.dt_s = tick.dt_s * slot.decimation;
    if (slot.block->step(t) != StepStatus::ok) {
      ++slot.faults;
      continue;
    }
    slot.stepped_ok = true;
    for (std::size_t i = 0; i < slot.disagreement_size; ++i) slot.disagreement[i] = slot.mine[i] - slot.primary[i];
    double nis = std::numeric_limits<double>::quiet_NaN();
    const std::size_t m = slot.block->innovation_size();
    if (m > 0 && m <= slot.nu.size() && slot.block->innovation(slot.nu.data(), slot.s.data())) {
      nis = 0.0;
      for (std::size_t i = 0; i < m; ++i) nis += slot.nu[i] * slot.nu[i] / slot.s[i];
    }
    *slot.nis = nis;
  }
  if (f.warming) {
    f.warming->step(tick);  // a failing candidate is caught when it is installed (health)
    if (f.warming_left > 0) --f.warming_left;
  }
  const HealthSpec& h = f.health;
  if (!h.enabled) return status;

  const char* trip = nullptr;
  Block* primary = ops[f.op].block;
  if (status != StepStatus::ok) trip = primary->fault_reason();
  if (!trip && h.non_finite)
    for (const auto& r : f.ranges)
      for (std::size_t i = 0; i < r.size && !trip; ++i)
        if (!std::isfinite(r.primary[i])) trip = "non-finite output";
  BlockEntry* live = f.roles[0]->live.load(std::memory_order_relaxed);
  if (!trip && h.covariance_every > 0 && live->layout.covariance && tick.cycle % h.covariance_every == 0 &&
      f.state_values.size() >= live->layout.size() &&
      f.state_covariance.size() >= live->layout.size() * live->layout.size()) {
    primary->export_state(f.state_values.data(), f.state_covariance.data());
    for (std::size_t i = 0; i < live->layout.size() && !trip; ++i)
      if (!std::isfinite(f.state_values[i])) trip = "non-finite state";
    if (!trip && !positive_definite(f.state_covariance.data(), live->layout.size()))
      trip = "covariance not positive definite";
  }
  if (!trip && h.nis_window > 0) {
    const std::size_t m = primary->innovation_size();
    if (m > 0 && m <= f.nu.size() && primary->innovation(f.nu.data(), f.s.data())) {
      double nis = 0.0;
      for (std::size_t i = 0; i < m; ++i) nis += f.nu[i] * f.nu[i] / f.s[i];
      if (f.nis_count == h.nis_window) f.nis_sum -= f.nis_ring[f.nis_pos];
      else ++f.nis_count;
      f.nis_ring[f.nis_pos] = nis;
      f.nis_sum += nis;
      f.nis_pos = (f.nis_pos + 1) % h.nis_window;
      if (!std::isfinite(nis)) trip = "non-finite innovation";
      else if (f.nis_count == h.nis_window && f.nis_sum / h.nis_window > h.nis_threshold)
        trip = "innovation test failed (windowed mean NIS over threshold)";
    }
  }
  if (!trip && h.step_budget_ns > 0) {
    f.over_budget = step_ns > h.step_budget_ns ? f.over_budget + 1 : 0;
    if (f.over_budget >= h.budget_cycles) trip = "step time over budget";
  }
  if (!trip) return status;

  TripRecord record;
  record.cycle = tick.cycle;
  record.time_ns = tick.time_ns;
  record.family = static_cast<int>(&f - families.data());
  record.reason = trip;
  const int slot_index = h.fallback_slot;
  if (slot_index >= 0 && !f.fallback_used && f.shadows[static_cast<std::size_t>(slot_index)].stepped_ok) {
    // The fallback already stepped on this cycle's inputs: exchange roles and hand its outputs
    // to the primary storage now, so the blocks downstream use them in this very cycle.
    auto& slot = f.shadows[static_cast<std::size_t>(slot_index)];
    bool finite = true;
    for (const auto& r : f.ranges)
      for (std::size_t i = 0; i < r.size; ++i) finite = finite && std::isfinite(r.shadow[i]);
    if (finite) {
      exchange_roles(f, 0, slot_index + 1);
      for (const auto& r : f.ranges) std::memcpy(r.primary, r.shadow, r.size * sizeof(double));
      (void)slot;
      f.fallback_used = true;
      f.restart_health();
      record.fallback_slot = slot_index;
      push_trip(record);
      return StepStatus::ok;
    }
  }
  push_trip(record);
  reason = trip;
  return StepStatus::fault;
}


std::vector<Pipeline::HealthTrip> Pipeline::take_health_trips() {
  std::vector<HealthTrip> out;
  auto& im = *impl_;
  TripRecord t;
  while (im.trips.pop(t)) {
    HealthTrip h;
    h.cycle = t.cycle;
    h.time_ns = t.time_ns;
    h.reason = t.reason;
    if (t.family >= 0) {
      const Family& f = im.families[static_cast<std::size_t>(t.family)];
      h.block = f.primary->name;
      if (t.fallback_slot >= 0) {
        const BlockEntry* role = f.roles[static_cast<std::size_t>(t.fallback_slot + 1)];
        h.fallback = role->name;
        // After the exchange the fallback's instance runs in the primary role.
        const BlockEntry* live = f.roles[0]->live.load(std::memory_order_acquire);
        h.fallback_plugin = live ? live->plugin_name : "";
      }
    }
    out.push_back(std::move(h));
  }
  const std::uint64_t dropped = im.trips.dropped();
  if (dropped > im.trips_lost_reported) {
    HealthTrip h;
    h.reason = "health trips lost (ring full)";
    h.lost = dropped - im.trips_lost_reported;
    im.trips_lost_reported = dropped;
    out.push_back(std::move(h));
  }
  return out;
}

void Pipeline::Impl::parse_health(const YAML::Node& h) {
  if (!h) return;
  if (!h.IsMap()) {
    error(detail::location_of(h, file), "health", "expected a map `<block>: {fallback: ..., ...}`");
    return;
  }
  for (const auto& kv : h) {
    const std::string block_name = kv.first.as<std::string>();
    const std::string path = "health." + block_name;
    const SourceLocation where = detail::location_of(kv.first, file);
    BlockEntry* b = find_block(block_name);
    if (!b) {
      error(where, path, "no block named '" + block_name + "'");
      continue;
    }
    if (b->family < 0 || b->family_role != 0) {
      error(where, path, "'" + block_name + "' is " + (b->is_io() ? "an io block" : !b->shadow_of.empty() ? "a shadow" : "not a block that steps") +
                             "; the health monitor watches estimators and other non-io blocks of the cycle");
      continue;
    }
    if (!kv.second.IsMap()) {
      error(detail::location_of(kv.second, file), path, "expected a map (fallback, non_finite, ...)");
      continue;
    }
    Family& f = families[static_cast<std::size_t>(b->family)];
    Params p = detail::make_params(kv.second, path, file, diag);
    HealthSpec& spec = f.health;
    spec.enabled = true;
    spec.non_finite = p.flag("non_finite", true);
    const auto every = p.integer("covariance_check_every", 1);
    p.check(every >= 0 && every <= 1000000, "covariance_check_every", "must be in 0..1000000 cycles (0 = off)");
    spec.covariance_every = static_cast<std::uint32_t>(std::clamp<std::int64_t>(every, 0, 1000000));
    if (spec.covariance_every > 0 && b->layout.covariance) {
      f.state_values.assign(b->layout.size(), 0.0);
      f.state_covariance.assign(b->layout.size() * b->layout.size(), 0.0);
    }
    const auto window = p.integer("nis_window", 0);
    p.check(window >= 0 && window <= 1000000, "nis_window", "must be in 0..1000000 cycles (0 = off)");
    spec.nis_window = static_cast<std::uint32_t>(std::clamp<std::int64_t>(window, 0, 1000000));
    const std::size_t m = b->block->innovation_size();
    if (spec.nis_window > 0 && m == 0)
      p.fail("nis_window", "plugin " + b->plugin_name + " reports no innovation (innovation_size() = 0): no NIS test possible");
    const double probability = p.number("nis_false_alarm", 1e-6);
    p.check(probability > 0 && probability < 0.5, "nis_false_alarm",
            "must be in (0, 0.5): the chance that a healthy filter trips per window");
    if (p.has("nis_threshold")) {
      spec.nis_threshold = p.number("nis_threshold");
      p.check(spec.nis_threshold > 0, "nis_threshold", "must be > 0 (the window mean of NIS, whose expectation is the channel count)");
    } else if (spec.nis_window > 0 && m > 0) {
      // The window mean of NIS is chi-square with W m degrees of freedom divided by W (white,
      // consistent innovations): the threshold is that distribution's upper quantile at the
      // false-alarm probability, exact (lode/sdk/math/statistics; the Wilson-Hilferty (1931)
      // approximation used before is 7 % high for W m = 3 at 1e-6).
      const double k = static_cast<double>(spec.nis_window) * static_cast<double>(m);
      spec.nis_threshold = math::chi_square_quantile(1.0 - probability, k) / static_cast<double>(spec.nis_window);
    }
    if (spec.nis_window > 0) {
      f.nis_ring.assign(spec.nis_window, 0.0);
      f.nu.assign(std::max<std::size_t>(m, 1), 0.0);
      f.s.assign(f.nu.size(), 0.0);
    }
    const double budget_us = p.number("step_budget_us", 0.0);
    p.check(budget_us >= 0 && budget_us <= 1e6, "step_budget_us", "must be in [0, 1e6] us (0 = off)");
    spec.step_budget_ns = static_cast<std::int64_t>(std::llround(budget_us * 1e3));
    const auto cycles = p.integer("budget_cycles", 3);
    p.check(cycles >= 1 && cycles <= 100000, "budget_cycles", "must be in 1..100000 (consecutive cycles over budget)");
    spec.budget_cycles = static_cast<std::uint32_t>(std::clamp<std::int64_t>(cycles, 1, 100000));
    if (p.has("fallback")) {
      const std::string fb = p.text("fallback");
      int slot = -1;
      for (std::size_t r = 1; r < f.roles.size(); ++r)
        if (f.roles[r]->name == fb) slot = static_cast<int>(r) - 1;
      if (slot < 0) {
        std::string shadows;
        for (std::size_t r = 1; r < f.roles.size(); ++r) shadows += (shadows.empty() ? "" : ", ") + f.roles[r]->name;
        p.fail("fallback", "'" + fb + "' is not a shadow of '" + block_name + "' (declare it with `shadow_of: " + block_name +
                               "`" + (shadows.empty() ? "" : "; its shadows: " + shadows) +
                               "): the fallback must run every cycle to take over in the same cycle");
      } else if (f.roles[static_cast<std::size_t>(slot) + 1]->shadow_decimation != 1) {
        p.fail("fallback", "'" + fb + "' is decimated (shadow_decimation " +
                               std::to_string(f.roles[static_cast<std::size_t>(slot) + 1]->shadow_decimation) +
                               "): a fallback must step every cycle");
      } else {
        spec.fallback_slot = slot;
        const BlockEntry* role = f.roles[static_cast<std::size_t>(slot) + 1];
        for (std::size_t i = 0; i < f.ranges.size(); ++i)
          f.ranges[i].shadow = arena.data() + output_offset(*role, b->outputs[i].name);
      }
    }
    detail::report_unread_keys(p);
  }
}

}  // namespace lode
