// The base of the hardware acquisition boards (io.vme_pentek, io.socketcan_daq): a Block and a
// Board with the three ports every such board has (board_ports.hpp), declared and reset the
// same way, so a board writes only how it talks to its device.
//
// Threads: declare_ports() in configure(), zero_inputs() in activate() (loader thread); the
// ports themselves are read and written by step()/write()/drive_safe() on the RT thread.
#pragma once

#include "board_ports.hpp"
#include "lode/sdk/block.hpp"
#include "lode/sdk/board.hpp"
#include "lode/sdk/port.hpp"

namespace lode::plugins::boards {

class AcquisitionBoard : public Block, public Board {
 protected:
  /// configure(), last: command (when the board has `outputs`), signals and counts (`inputs`).
  void declare_ports(ConfigureContext& ctx, const Elements& outputs, const Elements& inputs) {
    declare_board_ports(ctx, command_, signals_, counts_, outputs, inputs);
  }
  /// activate(): signals and counts read 0 until the first read phase.
  void zero_inputs() noexcept {
    for (std::size_t i = 0; i < signals_.size(); ++i) signals_[i] = counts_[i] = 0.0;
  }

  InputPort command_;   ///< the outputs' values, each in its unit (write phase)
  OutputPort signals_;  ///< the inputs, calibrated, each in its unit (read phase)
  OutputPort counts_;   ///< the same inputs as the converter's integer codes
};

}  // namespace lode::plugins::boards
