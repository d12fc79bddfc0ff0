#include "estimator_signals.hpp"

namespace lode::cli {

std::vector<EstimatorSignal> estimator_signals(const Pipeline& p, std::vector<std::string>& notes) {
  std::vector<EstimatorSignal> out;
  const auto& mon = p.monitor();
  auto add = [&](const SignalRef& s, const std::string& role) {
    for (const auto& e : out)
      if (e.signal.name() == s.name()) return;
    out.push_back({s, role});
  };
  if (mon.estimate) add(*mon.estimate, "monitor.estimate");
  // A shadow runs on its primary's inputs: its output on the estimate's port is the
  // estimate it would give if it were swapped in.
  const std::string port = mon.estimate ? mon.estimate->port : "";
  for (const auto& sh : p.shadows()) {
    auto s = port.empty() ? std::nullopt : p.signal(sh.name + "." + port);
    if (s) add(*s, "shadow of " + sh.primary);
    else notes.push_back("shadow " + sh.name + " has no output '" + port + "' to compare");
  }
  return out;
}

}  // namespace lode::cli
