// Telemetry: what a pipeline publishes (the YAML `telemetry:` section) and the RT side of
// the bridge.
//
// The RT thread never talks to Fast DDS. After each cycle it copies the published signals,
// each at its own decimated rate, into wait-free single-producer rings (TelemetryTap); a
// non-RT thread of the DDS bridge (core/dds) drains them and publishes typed topics. A full
// ring drops the record and counts it; the RT thread never waits. At the end of a cycle
// that filled a ring it rings a PublishDoorbell, so the publisher sends the samples at once
// instead of at its next poll. The core itself does not depend on Fast DDS: a pipeline
// without a bridge (or built without one) runs unchanged.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lode/pipeline.hpp"
#include "lode/sample_ring.hpp"

namespace lode {

/// How participants find each other (the YAML `telemetry.transport` and `telemetry.network`).
struct TransportSpec {
  enum class Kind {
    loopback,      ///< shared memory + UDPv4 restricted to 127.0.0.1 (default; same host only)
    shm,           ///< shared memory only
    udp_loopback,  ///< UDPv4 on 127.0.0.1 only
    network,       ///< UDPv4 on the listed interfaces (+ shared memory for local peers)
  };
  Kind kind = Kind::loopback;
  std::vector<std::string> interfaces;     ///< network: IPv4 addresses of the NICs to use (allowlist)
  std::vector<std::string> initial_peers;  ///< unicast discovery peers ("10.0.0.2" or "10.0.0.2:7412")
  bool multicast = true;                   ///< network: SPDP multicast discovery (off = peers only)
};

[[nodiscard]] const char* to_string(TransportSpec::Kind kind);
/// The kind a name (as to_string writes it) stands for; nullopt for any other text.
[[nodiscard]] std::optional<TransportSpec::Kind> transport_kind_from(std::string_view name);

/// DDS Security (authentication + access control + encryption) with the builtin plugins.
/// Empty paths = security off. Paths are resolved relative to the pipeline file.
struct SecuritySpec {
  std::string ca_certificate;        ///< identity CA (PEM)
  std::string certificate;           ///< this participant's identity certificate (PEM)
  std::string private_key;           ///< its private key (PEM)
  std::string permissions_ca;        ///< permissions CA (PEM); defaults to ca_certificate
  std::string governance;            ///< signed governance document (S/MIME .p7s)
  std::string permissions;           ///< signed permissions document (S/MIME .p7s)
  [[nodiscard]] bool enabled() const { return !certificate.empty(); }
};

/// Who may command the stage. Off unless the YAML enables it.
struct CommandAccess {
  bool enabled = false;
  /// IPv4 addresses a command may come from ("127.0.0.1" also matches shared-memory peers
  /// on this host). Empty = any host.
  std::vector<std::string> allow_hosts;
  /// DDS participant names allowed to command (`lode set --name NAME`). Empty = any name.
  std::vector<std::string> allow_participants;
};

struct TelemetrySignal {
  SignalRef signal;
  std::uint32_t decimation = 1;  ///< publish every n-th cycle (cycle % n == 0)
  std::string topic;             ///< lode/<pipeline>/<block>/<port>
  [[nodiscard]] double rate_hz(double pipeline_rate_hz) const { return pipeline_rate_hz / decimation; }
};

/// Stage state topic: pose (+ twist, + covariance) of one estimator, as one sample.
struct StateSpec {
  SignalRef pose;
  std::optional<SignalRef> twist;
  std::optional<SignalRef> covariance;  ///< row-major n x n, n = pose (+ twist) elements
  std::uint32_t decimation = 1;
  std::string topic;  ///< lode/<pipeline>/state
};

struct TelemetrySpec {
  bool enabled = false;  ///< a `telemetry:` section is present
  int domain = 0;        ///< DDS domain id 0..232
  TransportSpec transport;
  SecuritySpec security;
  CommandAccess commands;
  std::vector<TelemetrySignal> signals;
  std::optional<StateSpec> state;
  double timing_rate_hz = 1.0;   ///< timing statistics topic
  /// The longest the publisher thread waits for the doorbell before it looks at the rings
  /// and the events anyway (samples normally wake it at once).
  double publish_period_s = 0.001;
  /// Signal and state topics: RELIABLE (retransmits lost packets) or BEST_EFFORT (default).
  /// Best effort because Fast DDS 2.9.1's reliable writer can deadlock its publisher thread
  /// while readers join and leave (seen in the churn test); on shared memory and loopback
  /// nothing is lost unless a reader falls behind, and receivers count every gap.
  /// Metadata, events, timing and commands are always reliable.
  bool reliable = false;
  std::uint32_t ring_records = 0;  ///< per-signal ring capacity; 0 = one second of samples (min 1024)
  std::uint32_t history = 0;       ///< DDS writer history depth; 0 = one second of samples (min 64)
  /// SCHED_FIFO priority of the publisher thread (`telemetry.priority`); 0 = normal scheduling.
  /// Below the RT thread's, which preempts it; by default kDefaultPublisherPriority when the
  /// pipeline runs real-time.
  int publisher_priority = 0;
};

/// The publisher's default SCHED_FIFO priority in a pipeline with realtime.priority > it: above
/// every normally scheduled thread (so a sample leaves when the RT thread rings, not when the
/// scheduler gets round to it), below the RT thread and, on PREEMPT_RT, the threaded
/// interrupt handlers (50) that carry the network's packets.
inline constexpr int kDefaultPublisherPriority = 10;

/// Topic names a person can guess from the YAML.
[[nodiscard]] std::string signal_topic(const std::string& pipeline, const std::string& block,
                                       const std::string& port);
[[nodiscard]] std::string pipeline_topic(const std::string& pipeline, const std::string& what);

/// Something the scheduler calls on the RT thread around every cycle.
class CycleHook {
 public:
  virtual ~CycleHook() = default;
  /// Before the pipeline's cycle (commands are applied here, at a cycle boundary).
  virtual void before_cycle(const Tick& /*tick*/) noexcept {}
  /// After the cycle, with the cycle's outputs in place.
  virtual void after_cycle(const Tick& /*tick*/) noexcept {}
  /// Last of all, once every hook's after_cycle has run: tell another thread the cycle's
  /// results are there. Wait-free, as everything on the RT thread.
  virtual void cycle_finished() noexcept {}
};

/// How the RT thread tells the publisher thread "new samples" without waiting and, usually,
/// without a system call: a futex word.
///
/// ring() (RT thread) increments the sequence and makes a FUTEX_WAKE only when the waiter has
/// said it is asleep in wait(). An eventfd would cost a write() every cycle, and on
/// PREEMPT_RT every such write takes the eventfd's wait-queue lock, which is a sleeping
/// (priority-inheriting) lock there. Here the RT thread pays one locked add and one load when
/// the publisher is awake; the FUTEX_WAKE, when it happens, takes the futex hash bucket lock
/// (on PREEMPT_RT also priority-inheriting, held only for the few instructions of another
/// futex call on the same bucket) and wakes a thread of lower priority, which does not
/// preempt the RT thread. The publisher keeps the syscall rare by being awake when the
/// samples come (see the bridge's publisher loop): `wakes()` counts the rings that had to
/// make one.
class PublishDoorbell {
 public:
  /// RT thread: new samples are in the rings. Never blocks.
  void ring() noexcept;
  /// The one waiting thread: sleep until the sequence differs from `seen`, wake_all() or
  /// `timeout`. False on timeout. Spurious returns are possible: compare sequence().
  bool wait(std::uint32_t seen, std::chrono::nanoseconds timeout) noexcept;
  /// Any thread: end a wait() now (stopping).
  void wake_all() noexcept;
  [[nodiscard]] std::uint32_t sequence() const noexcept { return sequence_.load(std::memory_order_acquire); }
  /// Rings that found the waiter asleep and made a system call to wake it.
  [[nodiscard]] std::uint64_t wakes() const noexcept { return wakes_.load(std::memory_order_relaxed); }
  /// Nanoseconds the RT thread spent in those system calls, in all (CLOCK_MONOTONIC read
  /// around each call: only rings that make one pay for the two reads).
  [[nodiscard]] std::uint64_t wake_ns() const noexcept { return wake_ns_.load(std::memory_order_relaxed); }

 private:
  // One cache line: the RT thread touches both in ring(), and the waiter both in wait().
  alignas(64) std::atomic<std::uint32_t> sequence_{0};
  std::atomic<std::uint32_t> sleeping_{0};
  std::atomic<std::uint64_t> wakes_{0};    ///< written by ring() only
  std::atomic<std::uint64_t> wake_ns_{0};  ///< written by ring() only
};

/// RT side of the telemetry: one ring per published signal (and one for the state).
/// Record layout: SampleRing header (cycle, stamp_ns = scheduled time, captured_ns =
/// CLOCK_MONOTONIC when it was copied) followed by the signal's values.
class TelemetryTap final : public CycleHook {
 public:
  TelemetryTap(const TelemetrySpec& spec, double pipeline_rate_hz);

  void after_cycle(const Tick& tick) noexcept override;
  /// Rings the doorbell if this cycle put a record into a ring (dropped ones included: the
  /// publisher is behind then and should run).
  void cycle_finished() noexcept override;
  [[nodiscard]] PublishDoorbell& doorbell() noexcept { return doorbell_; }
  [[nodiscard]] const PublishDoorbell& doorbell() const noexcept { return doorbell_; }

  struct Channel {
    const double* data = nullptr;
    std::size_t width = 0;
    std::uint32_t decimation = 1;
    std::unique_ptr<SampleRing> ring;
    // State channel only: up to three sources concatenated (pose, twist, covariance).
    const double* extra_data[2] = {nullptr, nullptr};
    std::size_t extra_width[2] = {0, 0};
  };
  /// Channels in the order of spec.signals, then the state channel if any.
  [[nodiscard]] std::vector<Channel>& channels() { return channels_; }
  [[nodiscard]] const std::vector<Channel>& channels() const { return channels_; }
  /// Records dropped over every ring (consumer too slow).
  [[nodiscard]] std::uint64_t dropped() const;
  /// Records offered to the rings (published or dropped).
  [[nodiscard]] std::uint64_t offered() const;

 private:
  std::vector<Channel> channels_;
  bool offered_this_cycle_ = false;  ///< RT thread only
  PublishDoorbell doorbell_;
};

}  // namespace lode
