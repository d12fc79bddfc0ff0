// The server side of telemetry: drains the RT thread's rings and publishes
// typed topics; receives commands, checks who sent them, hands them to the ControlService
// and publishes the reply. Everything here runs on non-RT threads.
#pragma once

#include <cstdint>
#include <memory>

#include "lode/control.hpp"
#include "lode/dds/participant.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/scheduler.hpp"
#include "lode/telemetry.hpp"

namespace lode::dds {

struct BridgeStats {
  std::uint64_t published = 0;          ///< signal/state samples written
  std::uint64_t ring_dropped = 0;       ///< records the RT thread could not hand over
  std::uint64_t commands_accepted = 0;  ///< commands handed to the ControlService
  std::uint64_t commands_refused = 0;   ///< from a host/participant that is not allowed
  std::uint64_t commands_malformed = 0; ///< dropped: their bytes did not decode as a Command
  int publisher_priority = 0;           ///< the SCHED_FIFO priority the publisher got; 0 = normal scheduling
};

class TelemetryBridge {
 public:
  /// Create the participant, topics, writers (and the command reader when
  /// spec.commands.enabled), publish every SignalInfo, and start the publisher thread.
  /// `control` may be null when commands are disabled.
  static Expected<std::unique_ptr<TelemetryBridge>> start(const Pipeline& pipeline,
                                                          const TelemetrySpec& spec,
                                                          TelemetryTap& tap, const RunStats& stats,
                                                          EventLog& events, ControlService* control,
                                                          const ParticipantOptions& options);
  virtual ~TelemetryBridge() = default;

  /// Publish everything still in the rings and the events posted so far (end of run).
  virtual void flush() = 0;
  /// Data readers currently matched on the signal topics (sum over topics).
  [[nodiscard]] virtual std::size_t matched_readers() const = 0;
  [[nodiscard]] virtual BridgeStats stats() const = 0;
  /// Stop the threads and delete every entity (also done by the destructor).
  virtual void stop() = 0;
};

}  // namespace lode::dds
