// `lode run` under systemd (Type=notify): tells the service manager when the pipeline is
// really running, what it is doing, and that its real-time loop is still making progress.
//
//   READY=1      once the pipeline is active and the loop has run a cycle: a unit ordered
//                after lode@X finds the loop running, not merely the process started;
//   STATUS=...   about once a second (cycle, rate, overruns, faults), for `systemctl status`;
//   WATCHDOG=1   every half WatchdogSec, from the non-real-time side, only if the loop's cycle
//                counter advanced since the last ping. A loop stuck inside a step() leaves the
//                rest of the process alive (this side would happily keep pinging), so progress
//                is what is checked: without it the pings stop, systemd sends WatchdogSignal
//                (SIGABRT), the crash guard drives the outputs safe and the unit restarts;
//   STOPPING=1   when the stop begins (SIGTERM, end of the duration, a fault), then a final
//                STATUS with the outcome.
//
// Without $NOTIFY_SOCKET (not started by systemd) every call does nothing.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace lode::cli {

class ServiceNotifier {
 public:
  /// Reads $NOTIFY_SOCKET and the watchdog interval ($WATCHDOG_USEC, sd_watchdog_enabled()).
  ServiceNotifier();

  [[nodiscard]] bool active() const { return active_; }
  /// The interval systemd expects pings within (zero: no watchdog).
  [[nodiscard]] std::chrono::microseconds watchdog_interval() const { return watchdog_; }

  /// What on_idle() did, for the caller to log.
  enum class Idle { nothing, stalled };
  /// From the run's idle loop (non-RT), with the loop's count of cycles run: sends READY=1
  /// after the first cycle, STATUS about once a second (`status` is only called then) and
  /// the watchdog ping if the count advanced. Returns `stalled` once, the first time a ping is
  /// withheld because the loop made no progress for half the watchdog interval.
  Idle on_idle(std::uint64_t cycles_run, const std::function<std::string()>& status);
  /// STOPPING=1 with a STATUS (once; later calls do nothing).
  void stopping(const std::string& status);
  /// The last STATUS, e.g. the run's outcome.
  void status(const std::string& status);
  [[nodiscard]] bool ready_sent() const { return ready_sent_; }

 private:
  void send(const std::string& state);

  using SteadyClock = std::chrono::steady_clock;
  bool active_ = false;
  std::chrono::microseconds watchdog_{0};
  bool ready_sent_ = false;
  bool stopping_sent_ = false;
  bool stall_reported_ = false;
  std::uint64_t cycles_at_last_ping_ = 0;
  SteadyClock::time_point last_ping_ = SteadyClock::now();
  SteadyClock::time_point last_status_ = SteadyClock::now();
};

}  // namespace lode::cli
