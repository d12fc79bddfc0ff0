// The client side of the local command channel: where the sockets live, which pipelines
// answer on this host, and sending one command.
#include <dirent.h>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>

#include "local_control.hpp"
#include "local_socket.hpp"

namespace lode::cli {

using local_socket::connect_unix;
using local_socket::errno_text;
using local_socket::peer_of;
using Clock = std::chrono::steady_clock;

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
