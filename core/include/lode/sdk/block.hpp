// Blocks: the units a pipeline is composed of. This is the whole contract of the cycle; what
// some blocks have beyond it are optional interfaces the loader finds once after configure():
// Board (lode/sdk/board.hpp: io blocks' write phase and safe state), Tunables
// (lode/sdk/tunables.hpp: `lode set`) and EstimatorState (lode/sdk/estimator_state.hpp: hot
// swap and health monitoring).
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
#pragma once

#include <cstdint>

#include "lode/sdk/component.hpp"
#include "lode/sdk/configure_context.hpp"
#include "lode/sdk/json.hpp"
#include "lode/sdk/status.hpp"

namespace lode {

struct Tick {
  std::uint64_t cycle = 0;   ///< 0 on the first cycle
  std::int64_t time_ns = 0;  ///< scheduled (not measured) time of this cycle since start
  double dt_s = 0.0;         ///< period of the rate group
};

enum class StepStatus : std::uint8_t { ok = 0, fault = 1 };

class Block : public virtual Component {
 public:
  /// Read parameters, declare ports (each one listed in the plugin's port table), allocate,
  /// compute gains. Report every problem.
  virtual Status configure(ConfigureContext& ctx) = 0;
  /// Ports are bound: reset internal state, write initial outputs.
  virtual Status activate() { return {}; }
  /// The cycle (read phase for io blocks). RT-safe.
  virtual StepStatus step(const Tick& tick) noexcept = 0;
  virtual void deactivate() noexcept {}
  /// Derived quantities for `lode describe` (discretised coefficients, gains, ...).
  virtual void describe(Json& /*out*/) const {}

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
