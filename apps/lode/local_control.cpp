#include "local_control.hpp"

#include "lode/pipeline.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>

namespace lode::cli {

namespace {

using Clock = std::chrono::steady_clock;

std::string errno_text(int e) { return std::strerror(e); }


bool fill_address(const std::string& path, sockaddr_un& addr, std::string& error) {
  std::memset(&addr, 0, sizeof addr);
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path) {
    error = "socket path " + path + " is " + std::to_string(path.size()) + " bytes, longer than the " +
            std::to_string(sizeof addr.sun_path - 1) + " a Unix socket allows (use a shorter XDG_RUNTIME_DIR)";
    return false;
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return true;
}

/// The directory exists (created 0700 if not, parents too: a test may point XDG_RUNTIME_DIR
/// at a fresh path), is a real directory, ours, and private.
Status ensure_private_dir(const std::string& dir) {
  const auto make = [](const std::string& d) { return ::mkdir(d.c_str(), 0700) == 0 ? 0 : errno; };
  int e = make(dir);
  if (e == ENOENT) {
    for (std::size_t at = dir.find('/', 1); at != std::string::npos; at = dir.find('/', at + 1))
      make(dir.substr(0, at));  // a failure shows in the retry below
    e = make(dir);
  }
  if (e != 0 && e != EEXIST)
    return Status::error("cannot create " + dir + ": " + errno_text(e) +
                         (std::getenv("XDG_RUNTIME_DIR") ? " (check XDG_RUNTIME_DIR)" : ""));
  struct stat st {};
  if (::lstat(dir.c_str(), &st) != 0) return Status::error("cannot stat " + dir + ": " + errno_text(errno));
  if (!S_ISDIR(st.st_mode)) return Status::error(dir + " exists and is not a directory (a symlink?); not using it for the command socket");
  if (st.st_uid != ::geteuid())
    return Status::error(dir + " belongs to uid " + std::to_string(st.st_uid) + ", not to you (uid " +
                         std::to_string(::geteuid()) + "): refusing to put the command socket there (set XDG_RUNTIME_DIR)");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return Status::error(dir + " has mode " + mode + ": other users could reach the command socket; run `chmod 700 " +
                         dir + "` (only the owner may command a pipeline)");
  }
  return {};
}

/// SO_PEERCRED of a connected Unix socket.
std::optional<ucred> peer_of(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return std::nullopt;
  return cred;
}

/// Nonblocking connect; 0 = connected, else errno. EAGAIN: the backlog is full (it lives).
int connect_unix(const std::string& path, int& fd) {
  sockaddr_un addr{};
  std::string error;
  if (!fill_address(path, addr, error)) return ENAMETOOLONG;
  fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return errno;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) return 0;
  const int e = errno;
  ::close(fd);
  fd = -1;
  return e;
}

std::string pid_text(pid_t pid) { return pid > 0 ? "pid " + std::to_string(pid) : "pid unknown"; }

}  // namespace

// ---------------------------------------------------------------------------------------
RuntimeDirInputs runtime_dir_inputs_from_environment() {
  RuntimeDirInputs in;
  if (const char* xdg = std::getenv("XDG_RUNTIME_DIR")) in.xdg_runtime_dir = xdg;
  if (const char* home = std::getenv("HOME")) in.home = home;
  in.uid = ::geteuid();
  return in;
}

std::string local_control_dir(const RuntimeDirInputs& in) {
  if (!in.xdg_runtime_dir.empty()) return in.xdg_runtime_dir + "/lode";
  const auto ours = [&](const std::string& path, bool want_private) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode) && st.st_uid == in.uid &&
           (!want_private || (st.st_mode & 077) == 0);
  };
  // Without XDG_RUNTIME_DIR (a cron job, a service without a session), systemd-logind's
  // per-user directory is still the right place when it exists and is ours: unlike a name in
  // /tmp, no other user can create it first.
  const std::string user_run = in.run_user_root + "/" + std::to_string(in.uid);
  if (ours(user_run, true)) return user_run + "/lode";
  // /tmp is shared: anyone may create lode-<uid> (or a symlink of that name) before us. Such a
  // name is neither used nor allowed to lock the user out; the home directory, which only the
  // user can write, takes over. A lode-<uid> of our own with a loose mode stays the answer, so
  // the server can say how to fix it.
  const std::string in_tmp = in.tmp + "/lode-" + std::to_string(in.uid);
  struct stat st {};
  const bool absent = ::lstat(in_tmp.c_str(), &st) != 0 && errno == ENOENT;
  if (absent || ours(in_tmp, false) || in.home.empty()) return in_tmp;
  return in.home + "/.lode/run";
}

std::string local_control_dir() { return local_control_dir(runtime_dir_inputs_from_environment()); }

std::string local_control_socket(const std::string& pipeline) { return local_control_dir() + "/" + pipeline + ".sock"; }

std::optional<pid_t> probe_local_socket(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISSOCK(st.st_mode)) return std::nullopt;
  int fd = -1;
  const int e = connect_unix(path, fd);
  if (e == EAGAIN) return pid_t{0};  // listening, backlog full
  if (e != 0) return std::nullopt;   // ECONNREFUSED: stale
  const auto cred = peer_of(fd);
  ::close(fd);
  return cred ? cred->pid : pid_t{0};
}

std::vector<LocalPipeline> live_local_pipelines() {
  std::vector<LocalPipeline> out;
  const std::string dir = local_control_dir();
  DIR* d = ::opendir(dir.c_str());
  if (!d) return out;
  while (const dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() <= 5 || name.compare(name.size() - 5, 5, ".sock") != 0) continue;
    LocalPipeline p;
    p.pipeline = name.substr(0, name.size() - 5);
    p.path = dir + "/" + name;
    if (auto pid = probe_local_socket(p.path)) {
      p.pid = *pid;
      out.push_back(std::move(p));
    }
  }
  ::closedir(d);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.pipeline < b.pipeline; });
  return out;
}

// ---------------------------------------------------------------------------------------
LocalControlServer::LocalControlServer(ControlService& service, LocalControlOptions options)
    : service_(service), options_(std::move(options)) {}

Expected<std::unique_ptr<LocalControlServer>> LocalControlServer::start(ControlService& service,
                                                                        const std::string& pipeline,
                                                                        const LocalControlOptions& options) {
  if (!pipeline_name_problem(pipeline).empty())
    return Status::error("local control: pipeline name '" + pipeline +
                         "' cannot name a socket file (1-64 letters, digits, '_', '-', '.'; not starting with '.' or '-')");
  std::unique_ptr<LocalControlServer> s(new LocalControlServer(service, options));
  s->pipeline_ = pipeline;
  const std::string dir = options.dir.empty() ? local_control_dir() : options.dir;
  if (auto st = ensure_private_dir(dir); !st) return Status::error("local control: " + st.message());
  s->path_ = dir + "/" + pipeline + ".sock";
  sockaddr_un addr{};
  std::string error;
  if (!fill_address(s->path_, addr, error)) return Status::error("local control: " + error);

  // One run per pipeline and user: the lock decides (the kernel drops it when a run dies,
  // so a crash never blocks the next run); the pid inside is for the message.
  const std::string lock_path = dir + "/" + pipeline + ".lock";
  s->lock_fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (s->lock_fd_ < 0) return Status::error("local control: cannot open " + lock_path + ": " + errno_text(errno));
  if (::flock(s->lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    pid_t pid = probe_local_socket(s->path_).value_or(0);
    if (pid == 0) {
      char buf[32] = {};
      if (::pread(s->lock_fd_, buf, sizeof buf - 1, 0) > 0) pid = static_cast<pid_t>(std::atol(buf));
    }
    return Status::error("pipeline " + pipeline + " is already running locally (" + pid_text(pid) + ", socket " +
                         s->path_ + "); stop it first, or start this one with --no-local-control");
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(s->lock_fd_, 0) != 0 || ::pwrite(s->lock_fd_, pid.data(), pid.size(), 0) < 0) {
    // The pid is only for messages; the lock itself holds.
  }

  struct stat st {};
  if (::lstat(s->path_.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode))
      return Status::error("local control: " + s->path_ + " exists and is not a socket; not touching it (remove it by hand)");
    if (auto live = probe_local_socket(s->path_))
      return Status::error("pipeline " + pipeline + " is already running locally (" + pid_text(*live) + ", socket " +
                           s->path_ + "); stop it first, or start this one with --no-local-control");
    if (::unlink(s->path_.c_str()) != 0 && errno != ENOENT)
      return Status::error("local control: cannot remove the stale socket " + s->path_ + ": " + errno_text(errno));
    s->replaced_stale_ = true;
  }

  s->listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (s->listen_fd_ < 0) return Status::error("local control: socket(): " + errno_text(errno));
  if (::bind(s->listen_fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
    return Status::error("local control: cannot bind " + s->path_ + ": " + errno_text(errno));
  // The 0700 directory already keeps other users out between bind() and chmod().
  if (::chmod(s->path_.c_str(), 0600) != 0 || ::lstat(s->path_.c_str(), &st) != 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: cannot chmod 0600 " + s->path_ + ": " + errno_text(e));
  }
  s->dev_ = st.st_dev;
  s->ino_ = st.st_ino;
  if (::listen(s->listen_fd_, 16) != 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: listen on " + s->path_ + ": " + errno_text(e));
  }
  s->stop_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (s->stop_fd_ < 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: eventfd: " + errno_text(e));
  }
  LocalControlServer* raw = s.get();
  s->thread_ = std::thread([raw] { raw->serve(); });
  return s;
}

LocalControlServer::~LocalControlServer() { stop(); }

void LocalControlServer::stop() {
  if (thread_.joinable()) {
    const std::uint64_t one = 1;
    if (::write(stop_fd_, &one, sizeof one) < 0) {
      // An eventfd write only fails when the counter would overflow: it is already set.
    }
    thread_.join();
  }
  if (listen_fd_ >= 0) {
    // Remove the file only if it is still the one we bound (never another run's).
    struct stat st {};
    if (::lstat(path_.c_str(), &st) == 0 && st.st_dev == dev_ && st.st_ino == ino_) ::unlink(path_.c_str());
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  if (stop_fd_ >= 0) {
    ::close(stop_fd_);
    stop_fd_ = -1;
  }
  if (lock_fd_ >= 0) {
    ::close(lock_fd_);  // releases the flock; the lock file stays (unlinking it would race)
    lock_fd_ = -1;
  }
}

LocalControlStats LocalControlServer::stats() const {
  LocalControlStats s;
  s.connections = connections_.load();
  s.requests = requests_.load();
  s.malformed = malformed_.load();
  s.refused_clients = refused_.load();
  s.idle_closed = idle_closed_.load();
  return s;
}

void LocalControlServer::serve() {
  struct Conn {
    int fd = -1;
    std::string who;  ///< "local pid N uid U"
    std::string in, out;
    bool closing = false;  ///< no more input: close once `out` is sent
    Clock::time_point last_input = Clock::now();
  };
  std::vector<Conn> conns;
  std::vector<pollfd> fds;
  constexpr std::size_t kMaxPending = 1 << 20;  // reply bytes queued: stop reading above this

  const auto reply_line = [](const ControlReply& r) { return encode_reply(r) + "\n"; };
  const auto handle_line = [&](Conn& c, std::string line) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) return;  // blank lines (nc, telnet) are ignored
    std::uint64_t id = 0;
    auto request = decode_request(line, &id);
    ControlReply reply;
    if (!request) {
      malformed_.fetch_add(1);
      reply.id = id;
      reply.message = "malformed request: " + request.error();
    } else {
      requests_.fetch_add(1);
      request->client = request->client.empty() ? c.who : request->client + " via " + c.who;
      try {
        reply = service_.handle(*request, options_.handle_timeout);
      } catch (const std::exception& ex) {
        reply = ControlReply{};
        reply.message = request->kind + ": internal error: " + ex.what();
      }
      reply.id = request->id;
    }
    c.out += reply_line(reply);
  };

  for (;;) {
    fds.clear();
    fds.push_back({stop_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (const auto& c : conns) {
      short ev = 0;
      if (!c.closing && c.out.size() < kMaxPending) ev |= POLLIN;
      if (!c.out.empty()) ev |= POLLOUT;
      fds.push_back({c.fd, ev, 0});
    }
    // Wake for the earliest idle deadline (or not at all without clients).
    int wait_ms = -1;
    const auto now = Clock::now();
    for (const auto& c : conns) {
      if (c.closing) continue;
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(c.last_input + options_.idle_timeout - now);
      const int ms = static_cast<int>(std::clamp<long long>(left.count() + 1, 0, 1 << 30));
      wait_ms = wait_ms < 0 ? ms : std::min(wait_ms, ms);
    }
    if (::poll(fds.data(), fds.size(), wait_ms) < 0) {
      if (errno == EINTR) continue;
      break;  // cannot happen with valid fds; leaving ends the service, stop() still cleans up
    }
    if (fds[0].revents) break;
    const std::size_t polled = conns.size();  // conns accepted below are polled next round

    for (std::size_t k = 0; k < polled; ++k) {
      Conn& c = conns[k];
      const short re = fds[k + 2].revents;
      if (re & (POLLIN | POLLHUP | POLLERR)) {
        char buf[4096];
        const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
        if (n > 0) {
          c.in.append(buf, static_cast<std::size_t>(n));
          c.last_input = Clock::now();
        } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
          // End of input: a last line without '\n' (e.g. after shutdown(SHUT_WR)) still counts.
          if (n == 0 && !c.in.empty()) {
            handle_line(c, std::move(c.in));
            c.in.clear();
          }
          c.closing = true;
          if (n < 0) c.out.clear();  // the peer is gone
        }
        std::size_t nl;
        while (!c.in.empty() && (nl = c.in.find('\n')) != std::string::npos) {
          std::string line = c.in.substr(0, nl);
          c.in.erase(0, nl + 1);
          handle_line(c, std::move(line));
        }
        if (c.in.size() > options_.max_line) {
          refused_.fetch_add(1);
          ControlReply r;
          r.message = "malformed request: a request line longer than " + std::to_string(options_.max_line) +
                      " bytes without a newline; closing the connection";
          c.out += reply_line(r);
          c.in.clear();
          c.closing = true;
        }
      }
      if (!c.out.empty()) {  // replies go out at once; what does not fit waits for POLLOUT
        const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0) c.out.erase(0, static_cast<std::size_t>(n));
        else if (n < 0 && errno != EAGAIN && errno != EINTR) c.out.clear(), c.closing = true;
      }
    }
    // Clients silent for idle_timeout are told why and dropped (their slot is freed).
    for (std::size_t k = 0; k < polled; ++k) {
      Conn& c = conns[k];
      if (c.closing || Clock::now() - c.last_input < options_.idle_timeout) continue;
      idle_closed_.fetch_add(1);
      ControlReply r;
      r.message = "idle for " + std::to_string(options_.idle_timeout.count()) +
                  " ms without a request: closing the connection";
      c.out += reply_line(r);
      (void)::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      c.out.clear();
      c.closing = true;
    }
    // Drop finished clients.
    for (std::size_t k = conns.size(); k-- > 0;) {
      if (conns[k].closing && conns[k].out.empty()) {
        ::close(conns[k].fd);
        conns.erase(conns.begin() + static_cast<std::ptrdiff_t>(k));
      }
    }
    if (fds[1].revents & POLLIN) {
      for (;;) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (fd < 0) break;  // EAGAIN: all taken
        connections_.fetch_add(1);
        if (conns.size() >= options_.max_clients) {
          refused_.fetch_add(1);
          ControlReply r;
          r.message = "busy: too many local clients (" + std::to_string(options_.max_clients) +
                      " connected); retry";
          const std::string line = reply_line(r);
          (void)::send(fd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
          ::close(fd);
          continue;
        }
        Conn c;
        c.fd = fd;
        const auto cred = peer_of(fd);
        c.who = cred ? "local pid " + std::to_string(cred->pid) + " uid " + std::to_string(cred->uid) : "local client";
        conns.push_back(std::move(c));
      }
    }
  }
  for (auto& c : conns) ::close(c.fd);
}

// ---------------------------------------------------------------------------------------
Expected<ControlReply> local_send(const std::string& path, const ControlRequest& request,
                                  std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  const auto remaining_ms = [&]() -> int {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    return left <= 0 ? 0 : static_cast<int>(std::min<long long>(left, 1 << 30));
  };
  int fd = -1;
  for (;;) {
    const int e = connect_unix(path, fd);
    if (e == 0) break;
    if (e == EAGAIN && remaining_ms() > 0) {  // backlog full: the server is busy, not gone
      ::usleep(2000);
      continue;
    }
    switch (e) {
      case ENOENT:
        return Status::error("no local pipeline at " + path + " (is `lode run` running on this host, as this user, without --no-local-control?)");
      case ECONNREFUSED:
        return Status::error(path + " is stale: nothing listens there (left by a run that crashed; the next `lode run` of that pipeline replaces it)");
      case EACCES:
      case EPERM:
        return Status::error("permission denied on " + path + ": only the user who started the run may command it");
      case EAGAIN:
        return Status::error("the pipeline at " + path + " accepted no connection within " +
                             std::to_string(timeout.count()) + " ms (its command queue is full)");
      default:
        return Status::error("cannot connect to " + path + ": " + errno_text(e));
    }
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  // The file system already limits who can connect; this checks the other direction: the
  // socket we talk to is served by ourselves (or root), not by someone who planted it.
  if (const auto cred = peer_of(fd); cred && cred->uid != ::geteuid() && cred->uid != 0)
    return Status::error(path + " is served by uid " + std::to_string(cred->uid) + ", not by you (uid " +
                         std::to_string(::geteuid()) + "): not sending the command");

  const std::string line = encode_request(request) + "\n";
  std::size_t sent = 0;
  while (sent < line.size()) {
    const ssize_t n = ::send(fd, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      pollfd p{fd, POLLOUT, 0};
      if (::poll(&p, 1, remaining_ms()) == 0)
        return Status::error("could not send the request to " + path + " within " + std::to_string(timeout.count()) + " ms");
      continue;
    }
    const int send_errno = errno;
    // A server at its client limit answers "busy" and closes at once: say what it said
    // rather than "Broken pipe".
    char said[512];
    const ssize_t got = ::recv(fd, said, sizeof said - 1, MSG_DONTWAIT);
    if (got > 0) {
      std::string text(said, static_cast<std::size_t>(got));
      if (const auto nl = text.find('\n'); nl != std::string::npos) text.resize(nl);
      if (auto reply = decode_reply(text); reply && !reply->ok) return Status::error(path + ": " + reply->message);
    }
    return Status::error("sending to " + path + ": " + errno_text(send_errno));
  }
  std::string in;
  for (;;) {
    const auto nl = in.find('\n');
    if (nl != std::string::npos) {
      auto reply = decode_reply(in.substr(0, nl));
      if (!reply) return Status::error(path + ": " + reply.error());
      if (reply->id != request.id && reply->id != 0)
        return Status::error(path + ": reply to request " + std::to_string(reply->id) + ", expected " +
                             std::to_string(request.id));
      return reply;
    }
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, remaining_ms());
    if (ready == 0)
      return Status::error("no reply from " + path + " within " + std::to_string(timeout.count()) +
                           " ms (a swap may take longer: raise --timeout)");
    if (ready < 0 && errno == EINTR) continue;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n > 0) in.append(buf, static_cast<std::size_t>(n));
    else if (n == 0) return Status::error("the pipeline at " + path + " closed the connection without replying (did it stop?)");
    else if (errno != EAGAIN && errno != EINTR) return Status::error("reading from " + path + ": " + errno_text(errno));
  }
}

}  // namespace lode::cli
