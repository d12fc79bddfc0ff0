// `lode replay`: run the raw inputs of a recording through the recorded configuration (a
// bit-exactness check) and through other estimator sets, with a comparison report.
//
// Each configuration is turned into a replay by rewriting every block whose plugin is of
// kind io into io.replay playing that block's recorded outputs (the other lines of the file
// are untouched, so diagnostics keep the user's line numbers), then run on the simulated
// clock for exactly the recorded number of cycles.
//
// replay.cpp runs the command; replay_rewrite.cpp rewrites a configuration;
// replay_compare.cpp captures and compares what the replay produced; replay_report.cpp
// writes the report.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "analysis.hpp"
#include "lode/sdk/json.hpp"
#include "lode/pipeline.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/plugin_loader.hpp"
#include "lode/record/hdf5_recorder.hpp"
#include "lode/scheduler.hpp"

namespace lode::cli {

/// The configuration text with every io block replaced by
/// `{plugin: io.replay, recording: <recording>, block: <name>, inputs: <its inputs>}`.
/// Line numbers of everything else are kept (the replaced block's lines become one line
/// plus blank lines). `replaced` receives the names of the rewritten blocks; `note` is
/// set when the file could only be rewritten as a whole (flow-style `blocks:`), in which
/// case line numbers refer to the rewritten text. Unparsable text is returned unchanged
/// (loading it reports the syntax error at its place).
std::string rewrite_for_replay(const std::string& yaml, const std::string& recording, PluginRegistry& registry,
                               std::vector<std::string>& replaced, std::string& note);

/// Copies the compared signals and each estimator's NIS every cycle into storage sized
/// before the run (RT-safe: memcpy, EstimatorState::innovation(), arithmetic).
class CompareHook final : public CycleHook {
 public:
  struct Nis {
    Block* const* slot = nullptr;
    const Block* configured = nullptr;  ///< the instance whose innovation_size() sized `nu`
    const EstimatorState* estimator = nullptr;  ///< its estimator interface
    std::vector<double> nu, s;
    std::vector<double> values;  ///< per cycle; NaN when innovation() returned false
  };
  CompareHook(std::vector<SignalRef> signals, std::size_t cycles) : signals_(std::move(signals)), capacity_(cycles) {
    time_s_.assign(cycles, 0.0);
    for (const auto& s : signals_) values_.emplace_back(cycles * s.size(), std::nan(""));
  }
  /// Track the NIS of `name` (called before the run; the block's innovation_size() > 0).
  void track_nis(const Pipeline& p, const std::string& name) {
    Nis n;
    n.slot = p.block_slot(name);
    n.configured = p.block(name);
    n.estimator = dynamic_cast<const EstimatorState*>(n.configured);
    const std::size_t m = n.estimator ? n.estimator->innovation_size() : 0;
    n.nu.assign(m, 0.0);
    n.s.assign(m, 0.0);
    n.values.assign(capacity_, std::nan(""));
    nis_[name] = std::move(n);
  }
  // Row by row in the order the cycles run (a replay may skip cycle numbers, as its recording did).
  void after_cycle(const Tick& tick) noexcept override {
    if (rows_ >= capacity_) return;
    const std::size_t k = rows_++;
    time_s_[k] = static_cast<double>(tick.time_ns) * 1e-9;
    for (std::size_t i = 0; i < signals_.size(); ++i)
      std::memcpy(values_[i].data() + k * signals_[i].size(), signals_[i].data, signals_[i].size() * sizeof(double));
    for (auto& [name, n] : nis_) {
      const Block* b = n.slot ? *n.slot : nullptr;
      // A block swapped in by the health monitor may have another innovation size: its
      // NIS is not counted (its size cannot be asked on this thread).
      if (!b || b != n.configured || n.nu.empty() || !n.estimator->innovation(n.nu.data(), n.s.data())) continue;
      double sum = 0.0;
      for (std::size_t i = 0; i < n.nu.size(); ++i) sum += n.nu[i] * n.nu[i] / n.s[i];
      n.values[k] = sum;
    }
  }
  [[nodiscard]] analysis::Series series(std::size_t i) const {
    analysis::Series s;
    s.elements = *signals_[i].elements;
    s.values.assign(values_[i].begin(), values_[i].begin() + static_cast<std::ptrdiff_t>(rows_ * signals_[i].size()));
    return s;
  }
  [[nodiscard]] std::vector<double> time_s() const { return {time_s_.begin(), time_s_.begin() + static_cast<std::ptrdiff_t>(rows_)}; }
  [[nodiscard]] const Nis* nis(const std::string& name) const {
    auto it = nis_.find(name);
    return it == nis_.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::size_t rows() const { return rows_; }

 private:
  std::vector<SignalRef> signals_;
  std::size_t capacity_;
  std::size_t rows_ = 0;
  std::vector<double> time_s_;
  std::vector<std::vector<double>> values_;
  std::map<std::string, Nis> nis_;
};

struct BitCompare {
  std::size_t series = 0;
  std::size_t cycles = 0;
  std::string first_difference;  ///< empty when identical
  std::vector<std::string> only_in_one;
  /// One line per series that differs: its largest difference relative to the element's
  /// largest recorded magnitude, where and when ("largest relative difference 2.1e-16 in
  /// ukf.state.gap at cycle 812"), so a last-bit reordering (~1e-16 .. 1e-10) tells itself
  /// apart from a real change.
  std::vector<std::string> largest_differences;
};

/// The recording at `recorded` against the replay at `replayed`, series by series, bit for
/// bit; the first difference is named. Reads one series of each file at a time, so what it
/// holds is the largest series twice, not two whole recordings.
Expected<BitCompare> compare_recording_files(const std::string& recorded, const std::string& replayed);

struct EstimatorStats {
  std::string signal;  ///< block.port
  std::string block;
  std::string plugin;
  std::string role;    ///< "monitor.estimate", "shadow of kf", "--estimate"
  struct Element {
    std::string name, unit;
    double bias = NAN, rms = NAN, max_abs = NAN, noise_std = NAN;
  };
  std::vector<Element> elements;
  std::size_t nis_channels = 0;
  std::size_t nis_cycles = 0;
  double nis_mean = NAN, nis_in_95 = NAN, nis_lo = NAN, nis_hi = NAN;
  double median_step_us = NAN;
};

struct ConfigResult {
  std::string label;        ///< what the user named (config file or "recorded configuration")
  bool recorded = false;
  std::string output;
  std::uint64_t cycles = 0;
  double wall_s = 0, speed = 0;
  std::string digest;
  std::string digest_algorithm;  ///< the recording's (output_digest_algorithm)
  std::string reference;    ///< "" when none
  std::vector<EstimatorStats> estimators;
  std::vector<std::string> notes;
};

/// Error (against the reference, when there is one), hold-window noise, NIS against its
/// two-sided 95 % chi-square interval, and median step time of every estimator in
/// `estimators` (the first hook series, in order); the reference is the hook's series
/// `reference_index` (-1: none). Notes what could not be computed.
void estimator_statistics(const CompareHook& hook, const Pipeline& pipeline, int reference_index,
                          std::vector<EstimatorStats>& estimators, std::vector<std::string>& notes);

/// The comparison report, as Markdown (printed, --report R.md) and JSON (--report R.json).
struct ReplayReport {
  std::string markdown;
  Json json;
};
ReplayReport replay_report(const std::string& recording, const std::string& pipeline, std::size_t cycles,
                           double rate_hz, const std::vector<ConfigResult>& results, bool bit_identical,
                           bool faulted);

}  // namespace lode::cli
