// Commands to a running pipeline: set or read a runtime parameter, swap an estimator,
// start/stop recording. Transport-independent: the DDS bridge, a local
// CLI and tests all go through ControlService::handle().
//
// Validation happens off the RT thread (block exists, parameter is tunable, value parses,
// is in range); the change itself is handed to the RT thread through a one-slot wait-free
// mailbox and applied at the next cycle boundary (before_cycle), so a block never sees a
// parameter change in the middle of a step. The caller waits for the RT thread's answer
// (with a timeout) and gets the old and new value back. Every accepted change and every
// refused command is posted to the event log.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "lode/event_log.hpp"
#include "lode/sdk/tunables.hpp"
#include "lode/pipeline.hpp"
#include "lode/telemetry.hpp"

namespace lode {

struct ControlRequest {
  std::uint64_t id = 0;
  std::string kind;    ///< set | get | list | swap | promote | record_start | record_stop | status
  std::string block;   ///< set/get/list/swap
  std::string name;    ///< set/get: parameter; record_start: file
  std::string value;   ///< set: the new value, as text; swap: parameters (YAML flow map)
  std::string plugin;  ///< swap: the newcomer's plugin
  std::string client;  ///< who asked ("name@host"), for the event log
};

struct ControlReply {
  std::uint64_t id = 0;
  bool ok = false;
  std::string message;  ///< what happened, or precisely why not
  std::string value;    ///< get/set: the value now in force; list: one "name [min, max] unit" per line
};

class ControlService final : public CycleHook {
 public:
  using Handler = std::function<ControlReply(const ControlRequest&)>;
  /// A swap handler is given the lock that serialises commands: it may release it while it
  /// waits for something that takes long (a shadow period) and must not touch anything
  /// handle() guards until it holds it again (handle() takes it back if it was left unlocked).
  using SwapHandler = std::function<ControlReply(const ControlRequest&, std::unique_lock<std::mutex>& commands)>;

  ControlService(Pipeline& pipeline, EventLog& events);
  /// Waits for the swaps still under way (join_workers()).
  ~ControlService() override;
  ControlService(const ControlService&) = delete;
  ControlService& operator=(const ControlService&) = delete;

  /// RT thread, before each cycle: apply a pending change. Wait-free.
  void before_cycle(const Tick& tick) noexcept override;

  /// Whether an RT thread is cycling (then changes go through the mailbox). Set by the
  /// runner around Scheduler::run().
  void set_running(bool running) { running_.store(running, std::memory_order_release); }

  /// Validate and execute. Thread-safe (serialised); never called on the RT thread.
  ControlReply handle(const ControlRequest& request,
                      std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));

  /// Whether `request` is a swap or promote: served by the swap handler, for as long as the
  /// newcomer's shadow period.
  static bool is_swap(const ControlRequest& request) { return request.kind == "swap" || request.kind == "promote"; }

  /// handle(), with its reply given to `answer` (called once). A swap or promote lasts as
  /// long as its newcomer's shadow period (minutes) and runs on a worker thread, so that the
  /// transport goes on taking commands meanwhile; everything else is answered before this
  /// returns. `answer` runs on the worker for a swap: what it reaches must outlive the swap,
  /// or the transport calls join_workers() before it goes away.
  void handle_async(const ControlRequest& request, std::function<void(ControlReply)> answer,
                    std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));
  /// Waits for every swap started by handle_async() to have answered (a swap ends with the run:
  /// its wait sees the loop stop).
  void join_workers();

  /// Swap and recording are implemented elsewhere (hot-swap, recorder); without a handler
  /// those commands are answered with an error that says so.
  void set_swap_handler(SwapHandler h) { swap_handler_ = std::move(h); }
  void set_record_handler(Handler h) { record_handler_ = std::move(h); }

  /// Parses "0.3", "1e-3", "true", "off", ... Empty optional + message on error.
  static bool parse_value(const std::string& text, const Tunable& t, double& value, std::string& error);

 private:
  struct Entry {
    std::string block;
    Block* const* slot = nullptr;  ///< the pointer the RT thread steps (changes on a swap)
    Block* instance = nullptr;
    Tunables* interface = nullptr;  ///< the instance's runtime parameters (nullptr: none)
    std::vector<Tunable> tunables;
  };
  const Entry* find(const std::string& block) const;
  void refresh();
  ControlReply exchange(const ControlRequest& r, const Entry& e, std::size_t index, bool write,
                        double value, std::chrono::milliseconds timeout);

  Pipeline& pipeline_;
  EventLog& events_;
  std::vector<Entry> entries_;
  std::mutex mutex_;  ///< serialises handle(); never touched by the RT thread
  SwapHandler swap_handler_;
  Handler record_handler_;
  std::atomic<bool> running_{false};

  struct Worker {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::mutex workers_mutex_;
  std::vector<Worker> workers_;  ///< handle_async()'s swaps; the finished ones joined at the next call

  // One-slot mailbox: idle -> posted (caller) -> busy -> done (RT) -> idle (caller). A caller
  // that times out takes a posted request back (posted -> idle) unless the RT thread already
  // holds it (busy), in which case it waits the few nanoseconds until done.
  enum : int { kIdle = 0, kPosted = 1, kBusy = 2, kDone = 3 };
  alignas(64) std::atomic<int> state_{kIdle};
  Block* box_block_ = nullptr;
  Tunables* box_tunables_ = nullptr;
  Block* const* box_slot_ = nullptr;
  std::size_t box_index_ = 0;
  bool box_write_ = false;
  double box_value_ = 0.0;
  double box_previous_ = 0.0;
  double box_now_ = 0.0;
  bool box_ok_ = false;
  const char* box_why_ = "";
  std::uint64_t box_cycle_ = 0;
  std::int64_t box_time_ns_ = 0;
};

}  // namespace lode
