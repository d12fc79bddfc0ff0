#include "cli.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace lode::cli {

std::atomic<bool>& stop_requested() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {
extern "C" void on_stop_signal(int) { stop_requested().store(true); }
}  // namespace

void install_stop_handlers() {
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  // The terminal went away (an ssh session dropped, the window closed): stop as on Ctrl-C,
  // outputs driven safe and files closed, rather than die where the default action would.
  std::signal(SIGHUP, on_stop_signal);
}

void ignore_broken_pipes() {
  // By default a write to a pipe whose reader has gone (`lode run ... | head`, `lode echo X |
  // grep -m1 Y`) kills the process on the spot: a pipeline's outputs not driven safe, its
  // recording not closed, and a telemetry client gone from inside its shared-memory receive
  // thread, which could leave the pipeline unreachable over shared memory to every client
  // after it. Ignored, the write fails with EPIPE instead and each command decides.
  std::signal(SIGPIPE, SIG_IGN);
}

Status write_text_file(const std::string& path, std::string_view text) {
  const auto failed = [&](const char* what) {
    return Status::error("cannot write " + path + " (" + what + "): " + std::strerror(errno));
  };
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return failed("open");
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const Status error = failed("write");
      ::close(fd);
      return error;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) return failed("close");
  return {};
}

int finish_standard_output(int exit_code) {
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  const int flush_errno = errno;
  if (flushed && !std::ferror(stdout)) return exit_code;
  if (!flushed && flush_errno == EPIPE) return exit_code;
  if (flushed) {
    // An earlier write failed and its errno is gone: a pipe or socket whose reader left is
    // the usual reason, and not an error; anything else is.
    struct stat st {};
    if (::fstat(STDOUT_FILENO, &st) == 0 && (S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode))) return exit_code;
  }
  std::fprintf(stderr, "lode: the output could not be written in full%s%s\n", flushed ? "" : ": ",
               flushed ? "" : std::strerror(flush_errno));
  return exit_code == kExitOk ? kExitFault : exit_code;
}

double Args::number(const std::string& o, double fallback) const {
  const auto it = options.find(o);
  return it == options.end() ? fallback : std::strtod(it->second.c_str(), nullptr);
}

long long Args::integer(const std::string& o, long long fallback) const {
  const auto it = options.find(o);
  return it == options.end() ? fallback : std::strtoll(it->second.c_str(), nullptr, 10);
}

}  // namespace lode::cli
