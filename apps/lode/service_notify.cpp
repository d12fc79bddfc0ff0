#include "service_notify.hpp"

#include <systemd/sd-daemon.h>

#include <cstdlib>

namespace lode::cli {

ServiceNotifier::ServiceNotifier() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  active_ = socket != nullptr && *socket != '\0';
  std::uint64_t usec = 0;
  // > 0 only when $WATCHDOG_USEC is set (and $WATCHDOG_PID, if set, is this process).
  if (active_ && sd_watchdog_enabled(0, &usec) > 0) watchdog_ = std::chrono::microseconds(usec);
}

void ServiceNotifier::send(const std::string& state) {
  // A lost datagram is not worth stopping a run for; systemd acts on what it does not get.
  (void)sd_notify(0, state.c_str());
}

ServiceNotifier::Idle ServiceNotifier::on_idle(std::uint64_t cycles_run, const std::function<std::string()>& status) {
  if (!active_) return Idle::nothing;
  const auto now = SteadyClock::now();
  if (!ready_sent_) {
    if (cycles_run == 0) return Idle::nothing;  // active, but the loop has not run a cycle yet
    ready_sent_ = true;
    last_status_ = now;
    last_ping_ = now;
    cycles_at_last_ping_ = cycles_run;
    send("READY=1\nSTATUS=" + status() + (watchdog_.count() > 0 ? "\nWATCHDOG=1" : ""));
    return Idle::nothing;
  }
  if (stopping_sent_) return Idle::nothing;  // the final STATUS stays
  if (now - last_status_ >= std::chrono::seconds(1)) {
    last_status_ = now;
    send("STATUS=" + status());
  }
  if (watchdog_.count() == 0 || now - last_ping_ < watchdog_ / 2) return Idle::nothing;
  if (cycles_run != cycles_at_last_ping_) {
    cycles_at_last_ping_ = cycles_run;
    last_ping_ = now;
    stall_reported_ = false;
    send("WATCHDOG=1");
    return Idle::nothing;
  }
  // No cycle for half the interval: withhold the ping and let the watchdog expire.
  if (stall_reported_) return Idle::nothing;
  stall_reported_ = true;
  return Idle::stalled;
}

void ServiceNotifier::stopping(const std::string& status) {
  if (!active_ || stopping_sent_) return;
  stopping_sent_ = true;
  send("STOPPING=1\nSTATUS=" + status);
}

void ServiceNotifier::status(const std::string& status) {
  if (active_) send("STATUS=" + status);
}

}  // namespace lode::cli
