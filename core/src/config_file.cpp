#include "lode/config_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace lode {

namespace {

const char* file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

/// Closes the descriptor on every return path.
struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::optional<std::string> read_config_file(const std::string& path, Diagnostics& diagnostics,
                                            std::size_t max_bytes) {
  const SourceLocation where{path, 0, 0};
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer forever. The
  // descriptor is only read once fstat() says it is a regular file, where the flag is moot.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    diagnostics.add(where, "", std::string("cannot open the file: ") + std::strerror(errno));
    return std::nullopt;
  }
  const FdCloser closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    diagnostics.add(where, "", std::string("cannot stat the file: ") + std::strerror(errno));
    return std::nullopt;
  }
  if (!S_ISREG(st.st_mode)) {
    diagnostics.add(where, "", std::string("is ") + file_kind(st.st_mode) +
                                   ", not a configuration file (only regular files are read)");
    return std::nullopt;
  }
  const auto too_large = [&] {
    diagnostics.add(where, "", "is larger than " + std::to_string(max_bytes) +
                                   " bytes, the most a configuration file may be");
  };
  if (static_cast<std::uintmax_t>(st.st_size) > max_bytes) {
    too_large();
    return std::nullopt;
  }
  // Read to the end rather than st_size bytes (the file may grow while read), but never more
  // than one byte past the limit.
  std::string text;
  text.resize(max_bytes + 1);
  std::size_t used = 0;
  while (used < text.size()) {
    const ssize_t n = ::read(fd, text.data() + used, text.size() - used);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      diagnostics.add(where, "", std::string("cannot read the file: ") + std::strerror(errno));
      return std::nullopt;
    }
    used += static_cast<std::size_t>(n);
  }
  if (used > max_bytes) {
    too_large();
    return std::nullopt;
  }
  text.resize(used);
  return text;
}

}  // namespace lode
