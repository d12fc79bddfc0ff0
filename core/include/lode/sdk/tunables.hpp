// Optional interface: runtime parameters (`lode set`, remote commands).
//
// A block that has parameters worth changing while it runs derives from Tunables beside
// Block. The loader finds the interface once, off the real-time thread, after configure():
//
//   class Pid final : public lode::Block, public lode::Tunables { ... };
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace lode {

/// A parameter that may change while the block runs (`lode set`). Booleans are integers in
/// [0, 1] ("true"/"false"/"on"/"off" are accepted by the command path).
struct Tunable {
  std::string name;         ///< the YAML key it corresponds to
  std::string unit;         ///< SI unit, "1" for dimensionless, "bool" for a switch
  double min = -1e300;      ///< inclusive range; the command path refuses values outside
  double max = 1e300;
  bool integer = false;
  std::string description;
};

/// tunables() is called off the RT thread, once, after configure(). The command path checks
/// range and integrality against it, then calls set_tunable() on the RT thread at a cycle
/// boundary (or on any thread while the pipeline is not running): it must be RT-safe, take
/// effect from the next step(), and may refuse (return false with a static reason in `why`)
/// a value that the range alone does not exclude.
class Tunables {
 public:
  virtual ~Tunables();
  [[nodiscard]] virtual std::vector<Tunable> tunables() const = 0;
  [[nodiscard]] virtual double tunable_value(std::size_t index) const noexcept = 0;
  virtual bool set_tunable(std::size_t index, double value, const char*& why) noexcept = 0;
};

}  // namespace lode
