// Blocks: the units a pipeline is composed of.
//
// Lifecycle:
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
// Ports are re-bound by a hot swap (a replacement takes over the storage of the block it
// replaces, at a cycle boundary): read and write them through the port objects in every
// step(), never keep their data() pointers across steps.
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

#include "lode/sdk/component.hpp"
#include "lode/sdk/json.hpp"
#include "lode/sdk/model.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"
#include "lode/sdk/status.hpp"

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

/// What an estimator's exported state holds (see Block::state_layout()).
struct StateLayout {
  Elements elements;        ///< name and SI unit of each state element, in export order
  bool covariance = false;  ///< export_state() also writes the n x n covariance
  [[nodiscard]] std::size_t size() const { return elements.size(); }
  [[nodiscard]] bool empty() const { return elements.empty(); }
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

  /// @name Estimator state (hot swap).
  /// A block that estimates a state exports it so a replacement can warm-start from it at
  /// the cycle boundary of a hot swap, and reports its innovation so the health monitor and
  /// the shadow statistics can test it. The state exported is the prior of the coming
  /// step(): for a Kalman filter x⁻_k and P⁻_k, for GLSDC the warm-start pose.
  ///
  /// state_layout() is called off the RT thread after configure(); export_state(),
  /// import_state() and innovation() on the RT thread between steps: RT-safe, no
  /// allocation, sizes fixed by the layout.
  //@{
  /// Named elements with units (e.g. x, x_dot, x_ddot, y, ... in m, m/s, m/s^2); empty
  /// when the block has no exportable state.
  [[nodiscard]] virtual StateLayout state_layout() const { return {}; }
  /// Write n = layout size values and, when layout.covariance, n*n row-major covariance.
  virtual void export_state(double* /*values*/, double* /*covariance*/) const noexcept {}
  /// Take the state from `values` where present[i] != 0; keep the block's own initial
  /// value (after activate()) for the others. `covariance` (n*n, may be nullptr) gives
  /// P(i,j) for pairs where both are present; rows and columns of absent elements keep the
  /// block's own initial covariance with zero cross terms. Must leave a usable filter
  /// (symmetric positive definite P) whatever it is given; a block may symmetrise.
  virtual void import_state(const double* /*values*/, const double* /*covariance*/,
                            const std::uint8_t* /*present*/) noexcept {}
  /// Channels of the measurement update (0 = none): size of innovation()'s arrays.
  [[nodiscard]] virtual std::size_t innovation_size() const { return 0; }
  /// The last step's innovation nu = y - y_hat and its predicted variance S(i,i) (the
  /// diagonal of H P⁻ H' + R). False when the last step made no measurement update
  /// (coasting, first cycle). NIS (diagonal) = sum nu_i^2 / S(i,i).
  virtual bool innovation(double* /*residual*/, double* /*variance*/) const noexcept { return false; }
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
