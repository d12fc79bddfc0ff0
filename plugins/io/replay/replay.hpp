// io.replay: plays back the raw inputs of a recording (`lode run --record`) cycle by cycle,
// so any estimator set sees exactly the samples a recorded run saw (`lode replay`).
//
// @system
// name: io.replay
// input_ports:
//   command: [any size, any unit, optional]   # accepted and ignored (keeps the original wiring)
// output_ports:                                # read phase, start of the cycle
//   <port>: [the recorded elements and units of series "<block>.<port>", in recorded order]
// @endsystem
//
// configure() reads the chosen block's series once, not the whole recording (the raw series
// through lode::record::read_recording_shared: when `lode replay` has already read them, that
// copy is used) and plays them back. Series of different lengths or cycles, or a gap where the
// recorder lost cycles (its `dropped_cycles`), are a configuration error at `recording`; the
// cycles a real-time loop skipped after an overrun are not (no block ran them). step() copies
// the row recorded for tick.cycle of every series into its output: the replay is bit-exact
// (the doubles are copied, never recomputed). A cycle with no row faults; past the last row it
// faults "end of recording".
//
// Threads: configure()/activate()/describe() on the loader thread; step()/write() on the RT
// thread (memcpy from memory loaded in configure(), no allocation).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lode/sdk/block.hpp"
#include "lode/sdk/board.hpp"
#include "lode/record/hdf5_recorder.hpp"

namespace lode::plugins {

class ReplayBoard final : public Block, public Board {
 public:
  Status configure(ConfigureContext& ctx) override;
  Status activate() override;
  StepStatus step(const Tick& tick) noexcept override;
  void describe(Json& out) const override;
  /// A recording drives nothing: the command input is accepted and ignored, so the write
  /// phase and the safe state have nothing to do.
  StepStatus write(const Tick& /*tick*/) noexcept override { return StepStatus::ok; }
  void drive_safe() noexcept override {}

  /// Rows (cycles) available; the first one is recorded cycle first_cycle().
  [[nodiscard]] std::size_t rows() const noexcept { return rows_; }
  [[nodiscard]] std::uint64_t first_cycle() const noexcept { return first_cycle_; }
  /// Cycle numbers between the first and the last row that the recording has no row for: the
  /// periods its real-time loop skipped after overruns.
  [[nodiscard]] std::uint64_t skipped_cycles() const noexcept { return skipped_cycles_; }

 private:
  struct Stream {
    std::string port;                 ///< output name (the part after "<block>.")
    std::string kind;                 ///< recorded kind ("raw" for io outputs)
    std::size_t width = 0;
    Elements elements;                 ///< recorded names and units
    std::size_t rows = 0;
    const std::uint64_t* cycle = nullptr;  ///< recorded cycle of each row (in recording_)
    const double* values = nullptr;        ///< rows x width, row-major, bit for bit from the file
    OutputPort out;
  };
  /// Copy row `row` into every output.
  void copy_row(std::size_t row) noexcept;

  std::string path_;
  std::string block_;
  std::shared_ptr<const record::Recording> recording_;  ///< what the streams point into
  std::vector<Stream> streams_;
  std::size_t rows_ = 0;
  std::uint64_t first_cycle_ = 0;
  std::uint64_t skipped_cycles_ = 0;
  std::size_t next_row_ = 0;  ///< the row step() expects next (RT thread)
  std::vector<std::string> warnings_;  ///< from read_recording (e.g. a crashed writer's file)
  InputPort command_;
};

}  // namespace lode::plugins
