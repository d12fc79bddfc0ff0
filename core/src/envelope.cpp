#include "envelope.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lode::pipeline_detail {

void Envelope::add(Limit limit) {
  State s;
  s.previous.assign(limit.elements ? limit.elements->size() : 0, 0.0);
  states_.push_back(std::move(s));
  limits_.push_back(std::move(limit));
  flatten();
}

void Envelope::flatten() {
  symmetric_pairs_.clear();
  bound_pairs_.clear();
  rate_pairs_.clear();
  struct Element {
    const double* value;
    double min, max;
  };
  struct Rated {
    const double* value;
    double* previous;
    double max_rate;
  };
  std::vector<Element> symmetric, bounded;
  std::vector<Rated> rated;
  for (std::size_t l = 0; l < limits_.size(); ++l) {
    const Limit& limit = limits_[l];
    State& state = states_[l];
    // With an invalid budget a non-finite value is judged by its time, not its bounds: every
    // non-finite value must leave the fast path, so unbounded becomes +-DBL_MAX there.
    const double widest = limit.max_invalid_ns >= 0 ? std::numeric_limits<double>::max()
                                                    : std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < state.previous.size(); ++i) {
      const double min = std::max(limit.min[i], -widest), max = std::min(limit.max[i], widest);
      (min == -max ? symmetric : bounded).push_back({limit.data + i, min, max});
      if (limit.max_rate[i] < std::numeric_limits<double>::infinity())
        rated.push_back({limit.data + i, &state.previous[i], limit.max_rate[i]});
    }
  }
  // Element k with element k + 1, the last of an odd count with itself.
  const auto partner = [](std::size_t k, std::size_t n) { return k + 1 < n ? k + 1 : k; };
  for (std::size_t k = 0; k < symmetric.size(); k += 2) {
    const Element& a = symmetric[k];
    const Element& b = symmetric[partner(k, symmetric.size())];
    symmetric_pairs_.push_back({a.value, b.value, Pair{a.max, b.max}});
  }
  for (std::size_t k = 0; k < bounded.size(); k += 2) {
    const Element& a = bounded[k];
    const Element& b = bounded[partner(k, bounded.size())];
    bound_pairs_.push_back({a.value, b.value, Pair{a.min, b.min}, Pair{a.max, b.max}});
  }
  for (std::size_t k = 0; k < rated.size(); k += 2) {
    const Rated& a = rated[k];
    const Rated& b = rated[partner(k, rated.size())];
    rate_pairs_.push_back({a.value, b.value, a.previous, b.previous, Pair{a.max_rate, b.max_rate}});
  }
  states_settled_ = false;
}

void Envelope::reset() noexcept {
  for (State& s : states_) {
    s.have_previous = false;
    s.invalid_since_ns = -1;
  }
  states_settled_ = false;
  violated_ = false;
}

bool Envelope::breach(std::size_t limit, std::size_t element, Breach what, double value, double bound,
                      const Tick& tick) noexcept {
  if (!violated_) {
    violation_ = {limit, element, what, value, bound, tick.cycle, static_cast<double>(tick.time_ns) * 1e-9};
    violated_ = true;
  }
  return false;
}

bool Envelope::check(const Tick& tick) noexcept {
  // |v|: the sign bit cleared.
  constexpr PairMask kMagnitude = {0x7fffffffffffffff, 0x7fffffffffffffff};
  PairMask inside = {-1, -1};
  for (const SymmetricPair& b : symmetric_pairs_) {
    const Pair v = {*b.first, *b.second};
    inside &= reinterpret_cast<Pair>(reinterpret_cast<PairMask>(v) & kMagnitude) <= b.max;
  }
  for (const BoundPair& b : bound_pairs_) {
    const Pair v = {*b.first, *b.second};
    inside &= (v >= b.min) & (v <= b.max);
  }
  // A rate within its limit here is within it in check_limit, which computes it the same way
  // where it checks one (a previous value, both finite); anything else (no previous value
  // yet, a non-finite one: a NaN or infinite rate) is not plainly inside, and check_each()
  // decides.
  const Pair dt = {tick.dt_s, tick.dt_s};
  for (const RatePair& r : rate_pairs_) {
    const Pair change = Pair{*r.first, *r.second} - Pair{*r.previous_first, *r.previous_second};
    inside &= reinterpret_cast<Pair>(reinterpret_cast<PairMask>(change) & kMagnitude) / dt <= r.max_rate;
  }
  if (!(inside[0] & inside[1])) return check_each(tick);
  // What check_limit leaves behind when every value is inside, and finite where invalid values
  // have a budget (previous values are read only where a rate is limited; an odd element,
  // paired with itself, is stored twice).
  for (const RatePair& r : rate_pairs_) {
    *r.previous_first = *r.first;
    *r.previous_second = *r.second;
  }
  if (!states_settled_) {
    for (State& state : states_) {
      state.have_previous = true;
      state.invalid_since_ns = -1;
    }
    states_settled_ = true;
  }
  return true;
}

bool Envelope::check_each(const Tick& tick) noexcept {
  states_settled_ = false;
  for (std::size_t l = 0; l < limits_.size(); ++l)
    if (!check_limit(l, tick)) return false;
  return true;
}

bool Envelope::check_limit(std::size_t l, const Tick& tick) noexcept {
  {
    const Limit& limit = limits_[l];
    State& state = states_[l];
    const std::size_t n = state.previous.size();
    bool all_finite = true;
    for (std::size_t i = 0; i < n; ++i) all_finite = all_finite && std::isfinite(limit.data[i]);
    if (limit.max_invalid_ns >= 0) {
      if (all_finite) state.invalid_since_ns = -1;
      else if (state.invalid_since_ns < 0) state.invalid_since_ns = tick.time_ns;
      const std::int64_t invalid_ns = state.invalid_since_ns < 0 ? 0 : tick.time_ns - state.invalid_since_ns;
      if (state.invalid_since_ns >= 0 && invalid_ns > limit.max_invalid_ns) {
        std::size_t bad = 0;
        while (bad + 1 < n && std::isfinite(limit.data[bad])) ++bad;
        return breach(l, bad, Breach::invalid, static_cast<double>(invalid_ns) * 1e-9,
                      static_cast<double>(limit.max_invalid_ns) * 1e-9, tick);
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      const double v = limit.data[i];
      // A NaN fails a comparison: where invalid values have their own budget they are judged
      // by it alone, elsewhere a NaN is outside every bound.
      if (!std::isfinite(v) && limit.max_invalid_ns >= 0) continue;
      if (!(v >= limit.min[i])) return breach(l, i, Breach::below, v, limit.min[i], tick);
      if (!(v <= limit.max[i])) return breach(l, i, Breach::above, v, limit.max[i], tick);
      // Most limits bound no rate (max_rate +inf): no rate exceeds that, so skip the division.
      if (limit.max_rate[i] < std::numeric_limits<double>::infinity() && state.have_previous &&
          std::isfinite(state.previous[i]) && std::isfinite(v)) {
        const double rate = std::abs(v - state.previous[i]) / tick.dt_s;
        if (rate > limit.max_rate[i]) return breach(l, i, Breach::rate, rate, limit.max_rate[i], tick);
      }
    }
    for (std::size_t i = 0; i < n; ++i) state.previous[i] = limit.data[i];
    state.have_previous = true;
  }
  return true;
}

std::string Envelope::violation_text() const {
  if (!violated_) return "envelope: no violation";
  const Violation& v = violation_;
  const Limit& limit = limits_[v.limit];
  std::string element = std::to_string(v.element);
  std::string unit;
  if (limit.elements && v.element < limit.elements->size()) {
    element = (*limit.elements)[v.element].name;
    unit = (*limit.elements)[v.element].unit;
  }
  const std::string where = limit.signal + "." + element;
  char when[96];
  std::snprintf(when, sizeof when, " (cycle %llu, t = %.4f s)", static_cast<unsigned long long>(v.cycle), v.time_s);
  const auto number = [](double x, const std::string& u) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.4g", x);
    return u.empty() ? std::string(buf) : std::string(buf) + " " + u;
  };
  switch (v.breach) {
    case Breach::below:
      return "envelope: " + where + " = " + number(v.value, unit) + " is below its limit " + number(v.bound, unit) + when;
    case Breach::above:
      return "envelope: " + where + " = " + number(v.value, unit) + " is above its limit " + number(v.bound, unit) + when;
    case Breach::rate:
      return "envelope: " + where + " changes at " + number(v.value, unit + "/s") + ", faster than its limit " +
             number(v.bound, unit + "/s") + when;
    case Breach::invalid:
      return "envelope: " + limit.signal + " has been invalid (non-finite) for " + number(v.value * 1e3, "ms") +
             ", longer than its max_invalid_s of " + number(v.bound * 1e3, "ms") +
             " (an estimator fed by it runs on prediction alone)" + when;
  }
  return "envelope: violated";
}

}  // namespace lode::pipeline_detail
