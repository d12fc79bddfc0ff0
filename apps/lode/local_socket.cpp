#include "local_socket.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace lode::cli::local_socket {

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

std::optional<ucred> peer_of(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return std::nullopt;
  return cred;
}

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

}  // namespace lode::cli::local_socket
