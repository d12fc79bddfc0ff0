// What the remote commands share: a DDS participant from --domain/--transport/--peers/
// --interfaces/--name (or LODE_DDS_* in the environment), the stop conditions of echo and
// record, and the way set, swap and record --remote-* reach a pipeline: its local command
// socket when it runs on this host (local_control.hpp), else DDS (--local / --dds force one).
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "cli.hpp"
#include "lode/control.hpp"
#include "lode/dds/client.hpp"

namespace lode::cli {

using std::chrono::milliseconds;

/// "a,b,,c" -> {"a", "b", "c"}.
std::vector<std::string> split_list(const std::string& text);

/// A DDS client named lode-ROLE-PID@HOST (or --name); nullptr after printing why.
std::unique_ptr<dds::Client> make_client(const Args& args, const std::string& role);

/// On exit, like lost samples: how many samples `client` dropped because their bytes did not
/// decode (nothing printed when none were).
void report_malformed(const dds::Client& client, const char* command);

/// Says on stderr, and returns true, when more than one live pipeline goes by `pipeline`'s
/// name on the domain: their samples arrive mixed on the same topics.
bool warn_namesakes(const dds::Client& client, const std::string& pipeline, const char* command);

/// --wait in milliseconds.
milliseconds wait_option(const Args& args, double fallback_s);

/// "[unit]" after an element name, nothing for dimensionless.
std::string unit_suffix(const std::string& unit);

/// A value scaled to a readable unit (um, mrad, ...), fixed width for tables.
std::string format_scaled(double v, const std::string& unit);

/// Waits for stop conditions shared by echo and record: Ctrl-C, --duration, every followed
/// pipeline having posted its "stop" event (then a short grace for samples in flight).
class StopWatch {
 public:
  explicit StopWatch(double duration_s) : start_(std::chrono::steady_clock::now()), duration_s_(duration_s) {}
  void pipeline_stopped(const std::string& pipeline) {
    std::lock_guard lock(mutex_);
    stopped_.insert(pipeline);
    if (!stopped_at_) stopped_at_ = std::chrono::steady_clock::now();
  }
  void follow(const std::string& pipeline) {
    std::lock_guard lock(mutex_);
    followed_.insert(pipeline);
  }
  /// Whether `pipeline` has posted its "stop" event.
  bool stopped(const std::string& pipeline) {
    std::lock_guard lock(mutex_);
    return stopped_.count(pipeline) > 0;
  }
  void done() { done_.store(true); }
  /// Whoever read the standard output has gone (`lode echo X | head`): nothing more to print.
  void output_closed() { output_closed_.store(true); }
  /// Why it is time to stop ("" = not yet).
  std::string reason() {
    if (done_.load()) return "done";
    if (output_closed_.load()) return "output closed";
    if (stop_requested().load()) return "interrupted";
    if (duration_s_ > 0 && std::chrono::steady_clock::now() - start_ > std::chrono::duration<double>(duration_s_)) return "duration";
    std::lock_guard lock(mutex_);
    if (!followed_.empty() && stopped_at_ && std::chrono::steady_clock::now() - *stopped_at_ > milliseconds(700)) {
      bool all = true;
      for (const auto& p : followed_) all = all && stopped_.count(p);
      if (all) return "pipeline stopped";
    }
    return "";
  }

 private:
  std::chrono::steady_clock::time_point start_;
  double duration_s_;
  std::atomic<bool> done_{false};
  std::atomic<bool> output_closed_{false};
  std::mutex mutex_;
  std::set<std::string> followed_, stopped_;
  std::optional<std::chrono::steady_clock::time_point> stopped_at_;
};

/// A command to a pipeline, over its local socket when there is one, else over DDS.
///   --local: the socket or nothing; --dds: DDS only.
///   Which pipeline: --pipeline NAME, the "NAME/" prefix of the target (stripped here), or,
///   with neither, the one pipeline with a live local socket, else the one live on the DDS
///   domain (several: refused, naming them). `make` builds the request from the target
///   without its prefix; nullopt = usage error (already printed). Prints the reply.
///   `shadow_cycles`: the swap runs its newcomer as a shadow that long before it replies, so
///   the reply is awaited that much longer (at the rate the pipeline's status gives).
int send_command(const Args& args, const std::string& role, std::string target,
                 const std::function<std::optional<ControlRequest>(const std::string&)>& make,
                 std::uint64_t shadow_cycles = 0);

}  // namespace lode::cli
