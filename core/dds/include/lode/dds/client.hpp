// The client side: what `lode topics/echo/record/set/swap` use. Callbacks run on Fast DDS
// listener threads; keep them short.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lode/control.hpp"
#include "lode/dds/participant.hpp"

namespace lode::dds {

struct SignalMeta {
  std::string topic, pipeline, block, port, kind;  ///< kind: "signal" | "state"
  std::vector<std::string> names, units;
  double rate_hz = 0, pipeline_rate_hz = 0;
  std::uint32_t decimation = 1;
  std::uint32_t pose_size = 0, twist_size = 0, covariance_size = 0;
  bool reliable = false;  ///< the writer's reliability (the reader must not ask for more)
};

struct Sample {
  std::uint64_t cycle = 0;
  std::int64_t stamp_ns = 0;
  std::int64_t captured_ns = 0;
  std::int64_t received_ns = 0;  ///< CLOCK_MONOTONIC when the listener took it
  std::vector<double> values;    ///< state: pose, twist, covariance concatenated
  /// Which DDS writer sent it (a hash of its GUID) and that writer's sequence number for it
  /// (1, 2, ...; 0: unknown). One writer's samples follow each other by 1 unless some were
  /// lost on the way; a step in `cycle` with none in `sequence` is a cycle the pipeline never
  /// published (its loop skipped the period, or its telemetry could not hand the sample over,
  /// which TimingSample::telemetry_dropped counts).
  std::uint64_t writer = 0;
  std::uint64_t sequence = 0;
};

struct EventSample {
  std::uint64_t cycle = 0;
  std::int64_t stamp_ns = 0;
  std::string pipeline, kind, text;
};

struct TimingSample {
  std::string pipeline;
  std::uint64_t cycle = 0, executed = 0, overruns = 0, missed_periods = 0, telemetry_dropped = 0;
  double rate_hz = 0;
  struct Row { std::string name; std::uint64_t count; double p50_us, p90_us, p99_us, p999_us, max_us, mean_us; };
  Row wake_latency, cycle_time;
  std::vector<Row> blocks;
};

/// A live subscription; unsubscribes when destroyed.
class Subscription {
 public:
  virtual ~Subscription() = default;
  [[nodiscard]] virtual std::uint64_t received() const = 0;
};

class Client {
 public:
  static Expected<std::unique_ptr<Client>> create(const ParticipantOptions& options);
  virtual ~Client() = default;

  /// Metadata of every signal/state topic seen so far, waiting up to `wait` for at least
  /// one (transient-local: metadata of a running pipeline arrives shortly after joining).
  virtual std::vector<SignalMeta> signals(std::chrono::milliseconds wait) = 0;
  /// Resolve "lode/p/b/port", "b.port" or "p/b.port" against the known signals, waiting up
  /// to `wait`; an error lists the candidates (ambiguous) or what is live (not found).
  virtual Expected<SignalMeta> resolve(const std::string& what, std::chrono::milliseconds wait) = 0;

  /// Samples of one signal/state topic, in order, with its metadata.
  virtual Expected<std::unique_ptr<Subscription>> subscribe(
      const SignalMeta& meta, std::function<void(const SignalMeta&, const Sample&)> on_sample) = 0;
  /// Events / timing of every pipeline (empty `pipeline`) or one.
  virtual Expected<std::unique_ptr<Subscription>> subscribe_events(
      const std::string& pipeline, std::function<void(const EventSample&)> on_event) = 0;
  virtual Expected<std::unique_ptr<Subscription>> subscribe_timing(
      const std::string& pipeline, std::function<void(const TimingSample&)> on_timing) = 0;

  /// Send a command to `pipeline` and wait for its reply (error on timeout: "no reply
  /// within N ms: is the pipeline running with telemetry.commands.enabled?").
  virtual Expected<ControlReply> command(const std::string& pipeline, ControlRequest request,
                                         std::chrono::milliseconds timeout) = 0;
  /// Pipelines that have published SignalInfo.
  virtual std::vector<std::string> pipelines(std::chrono::milliseconds wait) = 0;
  /// How many live pipelines (their bridges' participants) go by `pipeline`'s name: more than
  /// one means two rigs or users run one configuration on this domain and share its topics.
  [[nodiscard]] virtual std::size_t namesakes(const std::string& pipeline) const = 0;
  /// Samples dropped so far because their bytes did not decode as the topic's type (a
  /// foreign or broken writer on the domain): never handed to a callback.
  [[nodiscard]] virtual std::uint64_t malformed_samples() const = 0;
};

}  // namespace lode::dds
