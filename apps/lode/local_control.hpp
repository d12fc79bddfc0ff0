// Local command channel for a running `lode run`: the same ControlService commands as the
// DDS bridge (set, get, list, swap, promote, record_start, record_stop, status), over a
// Unix-domain stream socket, so `lode set` / `lode swap` work on the RT host without Fast DDS.
//
// Where: $XDG_RUNTIME_DIR/lode/<pipeline>.sock; without XDG_RUNTIME_DIR, /run/user/<uid>/lode
// when that directory is the user's, else /tmp/lode-<uid> unless another user holds that name,
// then $HOME/.lode/run. The directory is 0700 and owned by the user, the socket 0600: the file system is the authentication (only the user who started the run, and root, can
// connect). Every request is logged with the peer's pid and uid (SO_PEERCRED).
//
// Wire format (local_wire.hpp): one flat JSON object per line each way.
// A malformed line gets an ok=false reply that says what is wrong and where; the connection
// stays open. Requests are served one at a time, in arrival order, whatever the client.
//
// Threads: the server owns one normal-priority thread (never the RT thread) that polls the
// listening socket, the clients and a stop eventfd; ControlService::handle() runs on it.
// Nothing here is called on the RT thread.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "local_wire.hpp"
#include "lode/control.hpp"
#include "lode/sdk/status.hpp"

namespace lode::cli {

/// What picks the runtime directory: the environment and the places looked at, so a test can
/// point them at a scratch folder.
struct RuntimeDirInputs {
  std::string xdg_runtime_dir;           ///< "" = unset
  std::string run_user_root = "/run/user";
  std::string tmp = "/tmp";
  std::string home;                      ///< "" = unset
  uid_t uid = 0;
};
RuntimeDirInputs runtime_dir_inputs_from_environment();
/// $XDG_RUNTIME_DIR/lode, else <run_user_root>/<uid>/lode when that is the user's private
/// directory, else <tmp>/lode-<uid> when it is absent or the user's, else <home>/.lode/run:
/// a name in /tmp that another user created first (a directory or a symlink) must not lock
/// the user out, nor be used. Not created; the server checks it is ours and 0700.
std::string local_control_dir(const RuntimeDirInputs& inputs);
std::string local_control_dir();
/// The socket of pipeline `name` in local_control_dir().
std::string local_control_socket(const std::string& pipeline);

/// A local socket that answered a connect: which pipeline, where, whose process.
struct LocalPipeline {
  std::string pipeline;
  std::string path;
  pid_t pid = 0;  ///< the server's pid (SO_PEERCRED), 0 if unknown
};
/// Probe one socket path: the server's pid if something listens there, else nullopt (no
/// file, not a socket, or a stale file from a crashed run: connect refused).
std::optional<pid_t> probe_local_socket(const std::string& path);
/// Every pipeline with a live socket in local_control_dir(), by name.
std::vector<LocalPipeline> live_local_pipelines();

// --- server ------------------------------------------------------------------------------
struct LocalControlOptions {
  std::string dir;  ///< "" = local_control_dir()
  std::chrono::milliseconds handle_timeout{2000};  ///< ControlService::handle's RT-boundary wait
  std::size_t max_clients = 16;
  std::size_t max_line = 64 * 1024;  ///< a longer request line is refused and the client dropped
  /// A client that sends nothing for this long is told so and disconnected: idle
  /// connections must not hold the max_clients slots and lock every command out.
  std::chrono::milliseconds idle_timeout{10000};
};

struct LocalControlStats {
  std::uint64_t connections = 0;
  std::uint64_t requests = 0;
  std::uint64_t malformed = 0;  ///< lines refused before reaching the ControlService
  std::uint64_t refused_clients = 0;  ///< over max_clients or line too long
  std::uint64_t idle_closed = 0;      ///< disconnected after idle_timeout without a request
};

class LocalControlServer {
 public:
  /// Create the directory (0700) and socket (0600), replace a stale socket, refuse when a
  /// live run of the same pipeline owns it (a lock file <pipeline>.lock, held for the
  /// server's life and released by the kernel if the process dies, decides), and start the
  /// server thread. `service` must outlive the server.
  static Expected<std::unique_ptr<LocalControlServer>> start(ControlService& service, const std::string& pipeline,
                                                             const LocalControlOptions& options = {});
  ~LocalControlServer();
  LocalControlServer(const LocalControlServer&) = delete;
  LocalControlServer& operator=(const LocalControlServer&) = delete;

  /// Stop the thread (promptly: it polls an eventfd; a request being handled finishes
  /// first, at most handle_timeout), close every client and remove the socket file if it is
  /// still ours. Idempotent.
  void stop();
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] LocalControlStats stats() const;
  /// True when start() found a socket file left by a crashed run and replaced it.
  [[nodiscard]] bool replaced_stale() const { return replaced_stale_; }

 private:
  LocalControlServer(ControlService& service, LocalControlOptions options);
  void serve();

  ControlService& service_;
  LocalControlOptions options_;
  std::string pipeline_;
  std::string path_;
  int listen_fd_ = -1;
  int stop_fd_ = -1;  ///< eventfd
  int lock_fd_ = -1;  ///< flock()ed <pipeline>.lock
  bool replaced_stale_ = false;
  dev_t dev_ = 0;     ///< identity of our socket file: never unlink another run's
  ino_t ino_ = 0;
  std::thread thread_;
  std::atomic<std::uint64_t> connections_{0}, requests_{0}, malformed_{0}, refused_{0}, idle_closed_{0};
};

// --- client ------------------------------------------------------------------------------
/// Send one request to the socket at `path` and wait for its reply (whole exchange bounded
/// by `timeout`). Errors say whether nothing runs there, a stale file is left, or the
/// socket belongs to another user.
Expected<ControlReply> local_send(const std::string& path, const ControlRequest& request,
                                  std::chrono::milliseconds timeout);

}  // namespace lode::cli
