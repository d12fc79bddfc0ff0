// Optional interface of io blocks (plugin kind io): the board's write phase and its safe state.
//
// An io block is split in two: Block::step() is the read phase at the start of the cycle (its
// outputs are sources of the graph) and Board::write() the write phase at its end (its inputs
// are sinks), so feedback through the plant never forms a cycle. The loader requires this
// interface of every plugin of kind io and of no other kind.
#pragma once

#include "lode/sdk/block.hpp"

namespace lode {

class Board {
 public:
  virtual ~Board();
  /// The write phase at the end of the cycle. RT-safe.
  virtual StepStatus write(const Tick& tick) noexcept = 0;
  /// Drive every output to its configured safe value. RT-safe; idempotent; also called from
  /// the crash guard after a fault of any block.
  virtual void drive_safe() noexcept = 0;
};

}  // namespace lode
