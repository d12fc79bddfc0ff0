#include "board_ports.hpp"

#include <string>

#include "lode/sdk/units.hpp"

namespace lode::plugins::boards {

Elements counts_of(const Elements& inputs) {
  Elements out = inputs;
  for (Element& e : out) e.unit = std::string(kDimensionless);
  return out;
}

void declare_board_ports(ConfigureContext& ctx, InputPort& command, OutputPort& signals, OutputPort& counts,
                         const Elements& outputs, const Elements& inputs) {
  if (!outputs.empty()) ctx.declare_input(command, "command", outputs, true);
  ctx.declare_output(signals, "signals", inputs);
  ctx.declare_output(counts, "counts", counts_of(inputs));
}

}  // namespace lode::plugins::boards
