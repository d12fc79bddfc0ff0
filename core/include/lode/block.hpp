// Blocks: the units a pipeline is composed of.
//
// Lifecycle (STYLE.md rule 7):
//
// | state        | entered by      | thread | may allocate | what is available              |
// |--------------|-----------------|--------|--------------|--------------------------------|
// | created      | plugin create() | any    | yes          | nothing                        |
// | configured   | configure(ctx)  | non-RT | yes          | params, declared ports (unbound)|
// | active       | activate()      | non-RT | yes          | bound ports (pointers valid)   |
// | stepping     | step()/write()  | RT     | NO           | ports                          |
// | inactive     | deactivate()    | non-RT | yes          | ports                          |
//
// step() is the real-time contract: no allocation, no locks, no system calls, no exceptions,
// no logging except rt_log(). It returns StepStatus; on a fault it records a static reason.
//
// I/O blocks (descriptor kind io) are split in two: step() is the read phase at the start of
// the cycle (their outputs are sources of the graph) and write() the write phase at its end
// (their inputs are sinks), so feedback through the plant never forms a cycle.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "lode/component.hpp"
#include "lode/json.hpp"
#include "lode/model.hpp"
#include "lode/params.hpp"
#include "lode/port.hpp"
#include "lode/status.hpp"

namespace lode {

struct Tick {
  std::uint64_t cycle = 0;   ///< 0 on the first cycle
  std::int64_t time_ns = 0;  ///< scheduled (not measured) time of this cycle since start
  double dt_s = 0.0;         ///< period of the rate group
};

enum class StepStatus : std::uint8_t { ok = 0, fault = 1 };

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

/// Owning handle to a model created from the pipeline's `models:` section.
template <typename M>
using ModelPtr = std::unique_ptr<M>;

/// What configure() may use. Implemented by the pipeline loader and by the test harness.
class ConfigureContext {
 public:
  virtual ~ConfigureContext() = default;

  virtual Params& params() = 0;
  [[nodiscard]] virtual const std::string& block_name() const = 0;
  [[nodiscard]] virtual double rate_hz() const = 0;
  [[nodiscard]] double period_s() const { return 1.0 / rate_hz(); }

  /// Declare an output. Storage is bound after every block is configured.
  virtual void declare_output(OutputPort& port, const std::string& name, Elements elements) = 0;

  /// Declare an input fed from the block's `inputs: {name: block.port}` entry.
  /// `expected` gives size and units ("*" = any unit); empty means "any size", in which case
  /// input_source() tells the size and units of what is connected.
  virtual void declare_input(InputPort& port, const std::string& name, Elements expected,
                             bool required = true) = 0;

  /// Elements of the output connected to input `name`, when the source has already been
  /// configured (every non-io block upstream is); nullptr otherwise or if not connected.
  [[nodiscard]] virtual const Elements* input_source(const std::string& name) const = 0;

  /// Create and configure the model named by parameter `key` (a name in `models:`).
  /// Returns nullptr after recording a diagnostic if it does not exist or fails.
  virtual std::unique_ptr<PlantModel> plant_model(std::string_view key) = 0;
  virtual std::unique_ptr<MeasurementModel> measurement_model(std::string_view key) = 0;
  virtual std::unique_ptr<ProcessModel> process_model(std::string_view key) = 0;
  /// Parameter `key` holds a list of model names (or one name): one model per name, in order.
  /// An entry that fails is reported and left out (the result is then shorter than the list).
  virtual std::vector<std::unique_ptr<MeasurementModel>> measurement_models(std::string_view key) = 0;
};

class Block : public virtual Component {
 public:
  /// Read parameters, declare ports, allocate, compute gains. Report every problem.
  virtual Status configure(ConfigureContext& ctx) = 0;
  /// Ports are bound: reset internal state, write initial outputs.
  virtual Status activate() { return {}; }
  /// The cycle (read phase for io blocks). RT-safe.
  virtual StepStatus step(const Tick& tick) noexcept = 0;
  /// io blocks only: the write phase at the end of the cycle. RT-safe.
  virtual StepStatus write(const Tick& /*tick*/) noexcept { return StepStatus::ok; }
  /// io blocks: drive every output to its configured safe value. RT-safe; idempotent.
  virtual void drive_safe() noexcept {}
  virtual void deactivate() noexcept {}
  /// Derived quantities for `lode describe` (discretised coefficients, gains, ...).
  virtual void describe(Json& /*out*/) const {}

  /// @name Runtime parameters (`lode set`, remote commands).
  /// tunables() is called off the RT thread, once, after configure(). The command path
  /// checks range and integrality against it, then calls set_tunable() on the RT thread at
  /// a cycle boundary (or on any thread while the pipeline is not running): it must be
  /// RT-safe, take effect from the next step(), and may refuse (return false with a static
  /// reason in `why`) a value that the range alone does not exclude.
  //@{
  [[nodiscard]] virtual std::vector<Tunable> tunables() const { return {}; }
  [[nodiscard]] virtual double tunable_value(std::size_t /*index*/) const noexcept { return 0.0; }
  virtual bool set_tunable(std::size_t /*index*/, double /*value*/, const char*& why) noexcept {
    why = "not tunable";
    return false;
  }
  //@}

  /// Reason of the last StepStatus::fault (a string literal).
  [[nodiscard]] const char* fault_reason() const noexcept { return fault_reason_; }

 protected:
  StepStatus fault(const char* reason) noexcept {
    fault_reason_ = reason;
    return StepStatus::fault;
  }

 private:
  const char* fault_reason_ = "";
};

}  // namespace lode
