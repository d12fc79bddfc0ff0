#include "read_in_child.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <csignal>
#include <cstring>
#include <mutex>
#include <optional>
#include <map>

namespace lode::record::detail {

namespace {

bool in_child = false;
int progress_fd = -1;  // in the child: the pipe the parent watches
// On the pipe: a byte per part read, then, if the child met an error, a marker and the message.
constexpr char kProgress = 1;
constexpr char kErrorFollows = 2;

/// Longest a child may go without finishing a part of the file (an attribute set, a series,
/// the events): only a damaged structure takes that long, not a large or slow file.
constexpr int kStallLimitMs = 20'000;

/// The verdict on each file checked or written by this process, by identity(): a damaged
/// file is refused again without another child.
std::mutex checked_mutex;
std::map<std::string, Status>& checked_files() {
  static std::map<std::string, Status> files;
  return files;
}

/// A regular file's file_identity(): a file rewritten since is checked again.
std::optional<std::string> identity(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return file_identity(st);
}

/// Signals that mean the library failed on the file, not that somebody stopped the child
/// (Ctrl-C reaches the whole process group: the parent handles that itself).
bool crash_signal(int signal) {
  switch (signal) {
    case SIGSEGV:
    case SIGBUS:
    case SIGFPE:
    case SIGILL:
    case SIGABRT:
    case SIGSYS:
    case SIGTRAP:
      return true;
    default:
      return false;
  }
}

/// The child's address space: what it has at the fork, twice the file (no part of the file
/// can hold more than the file), and 256 MiB for HDF5 and the reading. A damaged length then
/// makes an allocation fail at once instead of clearing gigabytes (seen: a 5 GB string).
rlim_t memory_allowance(const std::string& path) {
  std::uint64_t pages = 0;
  if (std::FILE* statm = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(statm, "%" SCNu64, &pages) != 1) pages = 0;
    std::fclose(statm);
  }
  struct stat st {};
  const std::uint64_t file = ::stat(path.c_str(), &st) == 0 ? static_cast<std::uint64_t>(st.st_size) : 0;
  return static_cast<rlim_t>(pages * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE)) + 2 * file + (256u << 20));
}

void write_all(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    data += n;
    size -= static_cast<std::size_t>(n);
  }
}

[[noreturn]] void run_child(const std::string& path, ReadWhole read_whole) {
  in_child = true;
  prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlives the reader that waits for it
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);  // a crash here is expected: no core file
  const rlim_t allowance = memory_allowance(path);
  const rlimit memory{allowance, allowance};
  setrlimit(RLIMIT_AS, &memory);
  for (int signal : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP}) std::signal(signal, SIG_DFL);
  // What glibc prints when the heap is found broken is the parent's to say, in its own words.
  if (const int null = ::open("/dev/null", O_WRONLY); null >= 0) {
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
  }
  const Status read = read_whole(path);
  if (!read) {
    const std::string report = std::string(1, kErrorFollows) + read.message();
    write_all(progress_fd, report.data(), report.size());
  }
  _exit(read ? 0 : 1);  // _exit: no atexit handlers, no stdio flushed twice
}

}  // namespace

std::string file_identity(const struct stat& st) {
  return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino) + ":" + std::to_string(st.st_size) + ":" +
         std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
}

void trust_written_file(const std::string& path) {
  if (auto id = identity(path)) {
    std::lock_guard lock(checked_mutex);
    checked_files()[*id] = Status::ok();
  }
}

void note_progress() {
  if (progress_fd < 0) return;
  write_all(progress_fd, &kProgress, 1);
}

Status read_first_in_child(const std::string& path, ReadWhole read_whole) {
  if (in_child) return {};
  const auto id = identity(path);
  if (!id) return {};  // missing, a folder, unreadable: the reader says which
  {
    std::lock_guard lock(checked_mutex);
    if (auto it = checked_files().find(*id); it != checked_files().end()) return it->second;
  }
  // The child writes a byte to the pipe after each part it has read; its end closes when it ends.
  int progress[2];
  if (pipe2(progress, O_CLOEXEC) != 0) return {};  // no descriptors to spare: read it here
  const pid_t child = fork();
  if (child < 0) {  // no process to spare: read it here, as without the check
    ::close(progress[0]);
    ::close(progress[1]);
    return {};
  }
  if (child == 0) {
    ::close(progress[0]);
    progress_fd = progress[1];
    run_child(path, read_whole);
  }
  ::close(progress[1]);

  bool stalled = false;
  std::string from_child;  // from the error marker on
  for (;;) {
    pollfd wait_for{progress[0], POLLIN, 0};
    const int ready = poll(&wait_for, 1, kStallLimitMs);
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) {
      stalled = true;
      break;
    }
    char bytes[4096];
    const ssize_t got = ::read(progress[0], bytes, sizeof bytes);
    if (got == 0 || (got < 0 && errno != EINTR && errno != EAGAIN)) break;  // the child has ended
    if (got > 0 && (!from_child.empty() || std::memchr(bytes, kErrorFollows, static_cast<std::size_t>(got))))
      from_child.append(bytes, static_cast<std::size_t>(got));
  }
  ::close(progress[0]);
  if (stalled) kill(child, SIGKILL);
  int status = 0;
  pid_t done;
  while ((done = waitpid(child, &status, 0)) < 0 && errno == EINTR) {
  }
  Status verdict;
  if (stalled) {
    verdict = Status::error("the file is damaged: the HDF5 library made no progress reading it for " +
                            std::to_string(kStallLimitMs / 1000) + " s (its structure sends the library round "
                            "in circles); nothing was read from it");
  } else if (done != child) {
    return {};  // reaped elsewhere (SIGCHLD ignored): no verdict
  } else if (WIFSIGNALED(status) && crash_signal(WTERMSIG(status))) {
    const char* name = sigabbrev_np(WTERMSIG(status));
    verdict = Status::error(std::string("the file is damaged: the HDF5 library crashed reading it (SIG") +
                            (name != nullptr ? name : std::to_string(WTERMSIG(status)).c_str()) +
                            " in a process that reads each recording once before lodestone does); nothing was "
                            "read from it");
  } else if (WIFEXITED(status) && WEXITSTATUS(status) == 1 && from_child.find(kErrorFollows) != std::string::npos) {
    verdict = Status::error(from_child.substr(from_child.find(kErrorFollows) + 1));
  } else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return {};  // stopped from outside (Ctrl-C reaches the child too): no verdict
  }
  std::lock_guard lock(checked_mutex);
  checked_files()[*id] = verdict;
  return verdict;
}

}  // namespace lode::record::detail
