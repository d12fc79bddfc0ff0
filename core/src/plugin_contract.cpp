// Out-of-line pieces of the plugin contract: the optional interfaces' destructors (their key
// functions, so that their type information lives once, in the core library, and the loader's
// dynamic_cast finds them in every plugin) and the names of kinds and directions.
#include "lode/sdk/board.hpp"
#include "lode/sdk/estimator_state.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/tunables.hpp"

namespace lode {

Board::~Board() = default;
Tunables::~Tunables() = default;
EstimatorState::~EstimatorState() = default;

const char* to_string(PluginKind kind) {
  switch (kind) {
    case PluginKind::source: return "source";
    case PluginKind::filter: return "filter";
    case PluginKind::estimator: return "estimator";
    case PluginKind::controller: return "controller";
    case PluginKind::io: return "io";
    case PluginKind::plant: return "plant";
    case PluginKind::sensor: return "sensor";
  }
  return "unknown";
}

const char* to_string(PortDirection direction) {
  return direction == PortDirection::in ? "in" : "out";
}

}  // namespace lode
