// The ports of an acquisition board (io.vme_pentek, io.socketcan_daq; io.sim's counts):
//   command  its outputs (DAC channels, RPDO entries), each in its unit: written at the end of
//            the cycle; required, and declared only when the board has outputs
//   signals  its inputs (ADC channels, TPDO entries), calibrated, each in its unit
//   counts   the same inputs as the raw integer codes the converter produced [1]
//
// Threads: configure time only.
#pragma once

#include "lode/sdk/block.hpp"
#include "lode/sdk/port.hpp"

namespace lode::plugins::boards {

/// The counts port's elements for these input channels: the same names, dimensionless.
Elements counts_of(const Elements& inputs);

/// Declares command (when `outputs` is not empty), signals and counts.
void declare_board_ports(ConfigureContext& ctx, InputPort& command, OutputPort& signals, OutputPort& counts,
                         const Elements& outputs, const Elements& inputs);

}  // namespace lode::plugins::boards
