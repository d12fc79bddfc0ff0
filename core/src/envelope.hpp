// Internal: the envelope supervisor, where a stage may physically be and what its commands may
// do (the `envelope:` section of a pipeline).
//
// The health monitor judges an estimator by its own statistics; it cannot tell that a loop
// which is internally consistent is steering the stage somewhere it must not go. A fallback
// estimator coasting on prediction alone is exactly that case: no NaN, a positive definite
// covariance, no innovation at all, and the true position drifting away by metres. The
// envelope judges the signals themselves: limits on positions (the simulated truth and the
// estimate), on the commanded outputs and their rate of change, and on how long a signal may
// stay invalid (an estimator's measurement: the time it may coast). A value outside drives
// every output safe before the cycle's write phase and faults the run.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/port.hpp"

namespace lode::pipeline_detail {

class Envelope {
 public:
  struct Limit {
    std::string signal;                  ///< "kf.pose"
    const double* data = nullptr;        ///< the role's storage (stable across hot swaps)
    const Elements* elements = nullptr;  ///< names and units, for the message
    std::vector<double> min, max;        ///< per element; -inf / +inf where not limited
    std::vector<double> max_rate;        ///< per element, units per second; +inf where not limited
    /// How long (scheduled time, so skipped periods count) the signal may hold a non-finite
    /// element; -1 = not limited (then a non-finite value fails any min or max it has).
    std::int64_t max_invalid_ns = -1;
  };

  Envelope() = default;
  // The fast path's entries point into limits_ and states_.
  Envelope(const Envelope&) = delete;
  Envelope& operator=(const Envelope&) = delete;

  void add(Limit limit);
  [[nodiscard]] bool empty() const { return limits_.empty(); }
  [[nodiscard]] const std::vector<Limit>& limits() const { return limits_; }
  /// Before the first cycle of a run: forget the previous values and the first violation.
  void reset() noexcept;
  /// RT: true while every limited value is inside; false at the first that is not (kept for
  /// violation_text()). Never allocates.
  bool check(const Tick& tick) noexcept;
  /// Off the RT thread, after a failed check(): "envelope: kf.pose.x = 2.31e-3 m is above its
  /// limit 2e-3 m (cycle 812, t = 1.015 s)".
  [[nodiscard]] std::string violation_text() const;

 private:
  enum class Breach { below, above, rate, invalid };
  struct State {
    std::vector<double> previous;
    bool have_previous = false;
    std::int64_t invalid_since_ns = -1;  ///< scheduled time of the first invalid sample of the run of them
  };
  struct Violation {
    std::size_t limit = 0, element = 0;
    Breach breach = Breach::above;
    double value = 0.0, bound = 0.0;
    std::uint64_t cycle = 0;
    double time_s = 0.0;
  };
  bool breach(std::size_t limit, std::size_t element, Breach what, double value, double bound,
              const Tick& tick) noexcept;
  /// Every limit in order, as specified, naming the first breach: the reference the fast path
  /// of check() defers to whenever it sees anything that is not plainly inside.
  bool check_each(const Tick& tick) noexcept;
  /// One limit of check_each(); updates its state (previous values, invalid since) when inside.
  bool check_limit(std::size_t l, const Tick& tick) noexcept;
  /// Rebuilds the flat arrays below from limits_ (at configure time, after each add()).
  void flatten();

  // The fast path: the envelope is checked every cycle, and nearly every cycle every value is
  // inside. The limited elements are flattened into pairs checked two at a time (one SSE2 or
  // NEON instruction per operation, through GCC's vector extensions), every pair's verdict
  // ANDed into one mask and branched on once: (values, max) where the bounds are symmetric
  // (max_abs, and the unbounded: |v| <= max is exactly -max <= v <= max, and false for a NaN),
  // (values, min, max) otherwise, and the rate-limited elements as pairs of their own. An odd
  // element is paired with itself. Anything not plainly inside hands the cycle to check_each().
  using Pair = double __attribute__((vector_size(16)));
  using PairMask = std::int64_t __attribute__((vector_size(16)));
  struct SymmetricPair {
    const double* first;
    const double* second;
    Pair max;
  };
  struct BoundPair {
    const double* first;
    const double* second;
    Pair min, max;
  };
  struct RatePair {
    const double* first;
    const double* second;
    double* previous_first;  ///< where the previous values are kept
    double* previous_second;
    Pair max_rate;
  };
  std::vector<SymmetricPair> symmetric_pairs_;
  std::vector<BoundPair> bound_pairs_;
  std::vector<RatePair> rate_pairs_;
  /// Every state holds what a fully inside check leaves (have_previous, not invalid): the
  /// fast path need not write them again. Cleared by reset() and by check_each().
  bool states_settled_ = false;

  std::vector<Limit> limits_;
  std::vector<State> states_;
  Violation violation_;
  bool violated_ = false;
};

}  // namespace lode::pipeline_detail
