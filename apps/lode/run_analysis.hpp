// What `lode run` says about a run when it ends (position noise in the hold window, estimation
// and tracking errors, every step response), computed one drained row at a time so that its
// memory does not grow with the run's length: a day at 800 Hz is 69 million rows.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <vector>

#include "analysis.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"

namespace lode::cli {

class RunAnalysis {
 public:
  /// The signals the pipeline's `monitor:` names, tapped on the RT thread.
  explicit RunAnalysis(const Pipeline& pipeline);
  ~RunAnalysis();
  RunAnalysis(const RunAnalysis&) = delete;
  RunAnalysis& operator=(const RunAnalysis&) = delete;

  /// The tap to add to the scheduler (RT side).
  [[nodiscard]] SignalTap& tap() { return *tap_; }
  /// Non-RT side: take every row the tap holds into the running statistics.
  void drain();
  /// Rows analysed so far, and the tap's drops.
  [[nodiscard]] std::uint64_t samples() const { return samples_; }
  [[nodiscard]] std::uint64_t dropped() const { return tap_->dropped(); }
  /// The `monitor.show` signal's values in the last row drained (empty before the first).
  [[nodiscard]] std::vector<double> last_shown() const;
  [[nodiscard]] const SignalRef* shown() const;
  /// One row laid out as the tap's records ([cycle, time_s, then each tapped signal at
  /// tap().column(i)]) that did not come through the tap: `lode plot` feeds a recording's
  /// rows through the same statistics, so its figures are the run summary's.
  void add_row(const double* row);
  /// Where finish() prints the summary (stdout by default; nullptr: nowhere).
  void print_to(std::FILE* out) { out_ = out; }
  /// Prints the summary and returns it as JSON members of the run summary.
  Json finish();

 private:
  struct Streams;

  const Pipeline& pipeline_;
  std::unique_ptr<SignalTap> tap_;
  int show_ = -1, estimate_ = -1, truth_ = -1, reference_ = -1;
  std::vector<int> extra_;
  std::vector<double> scratch_, last_row_;
  std::uint64_t samples_ = 0;
  double first_t_ = 0.0, last_t_ = 0.0;
  std::FILE* out_ = stdout;
  std::unique_ptr<Streams> streams_;
};

}  // namespace lode::cli
