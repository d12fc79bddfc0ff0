#include "local_control.hpp"

#include "local_socket.hpp"
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
#include <memory>
#include <mutex>
#include <utility>

namespace lode::cli {

namespace {

using Clock = std::chrono::steady_clock;

using local_socket::ensure_private_dir;
using local_socket::errno_text;
using local_socket::fill_address;
using local_socket::peer_of;

std::string pid_text(pid_t pid) { return pid > 0 ? "pid " + std::to_string(pid) : "pid unknown"; }

}  // namespace

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
    std::uint64_t id = 0;
    int pending = 0;  ///< swaps of this client still running on a worker thread
    int fd = -1;
    std::string who;  ///< "local pid N uid U"
    std::string in, out;
    bool closing = false;  ///< no more input: close once `out` is sent
    Clock::time_point last_input = Clock::now();
  };
  std::vector<Conn> conns;
  std::vector<pollfd> fds;
  constexpr std::size_t kMaxPending = 1 << 20;  // reply bytes queued: stop reading above this
  std::uint64_t next_conn_id = 0;

  // A swap can take as long as its shadow period (minutes): it runs on a thread of its own,
  // so `lode set` and the rest are answered meanwhile, and its reply is queued here when done.
  struct Finished {
    std::uint64_t conn;
    std::string line;
  };
  std::mutex finished_mutex;
  std::vector<Finished> finished;
  const int finished_fd = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);

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
      if (ControlService::is_swap(*request) && finished_fd >= 0) {
        ++c.pending;
        service_.handle_async(
            *request,
            [&, conn = c.id, id = request->id](ControlReply r) {
              r.id = id;
              {
                std::lock_guard lock(finished_mutex);
                finished.push_back({conn, reply_line(r)});
              }
              const std::uint64_t one = 1;
              if (::write(finished_fd, &one, sizeof one) < 0) {
                // The counter is already set: the loop wakes anyway.
              }
            },
            options_.handle_timeout);
        return;
      }
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
    fds.push_back({finished_fd, POLLIN, 0});
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
      if (c.closing || c.pending > 0) continue;  // not idle while its swap runs
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
    if (fds[2].revents & POLLIN) {
      std::uint64_t count = 0;
      if (::read(finished_fd, &count, sizeof count) < 0) {
        // EAGAIN: another round took it; the queue below is what counts.
      }
      std::vector<Finished> replies;
      {
        std::lock_guard lock(finished_mutex);
        replies.swap(finished);
      }
      for (auto& r : replies) {
        const auto it = std::find_if(conns.begin(), conns.end(), [&](const Conn& c) { return c.id == r.conn; });
        if (it == conns.end()) continue;  // the client has gone
        it->out += r.line;
        --it->pending;
      }
    }

    for (std::size_t k = 0; k < polled; ++k) {
      Conn& c = conns[k];
      const short re = fds[k + 3].revents;
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
      if (c.closing || c.pending > 0 || Clock::now() - c.last_input < options_.idle_timeout) continue;
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
      if (conns[k].closing && conns[k].out.empty() && conns[k].pending == 0) {
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
        c.id = next_conn_id++;
        c.fd = fd;
        const auto cred = peer_of(fd);
        c.who = cred ? "local pid " + std::to_string(cred->pid) + " uid " + std::to_string(cred->uid) : "local client";
        conns.push_back(std::move(c));
      }
    }
  }
  for (auto& c : conns) ::close(c.fd);
  // A swap still running ends with the run (its wait sees the loop stop); its reply reaches
  // the queue above, which goes away with this function.
  service_.join_workers();
  if (finished_fd >= 0) ::close(finished_fd);
}

// ---------------------------------------------------------------------------------------
}  // namespace lode::cli
