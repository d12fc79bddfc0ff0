#include "journal_output.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdarg>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace lode::cli {
namespace {

/// One prefixed stream: the text of its line not yet ended.
struct PrefixedStream {
  std::FILE* base = nullptr;
  int fd = -1;
  int priority = 6;
  std::string pending;
};

std::mutex& streams_mutex() {
  static std::mutex m;
  return m;
}

void write_all(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // the journal is gone: nothing better to do than drop the line
    done += static_cast<std::size_t>(n);
  }
}

ssize_t write_prefixed(void* cookie, const char* data, std::size_t size) {
  auto& s = *static_cast<PrefixedStream*>(cookie);
  const std::lock_guard lock(streams_mutex());
  s.pending.append(data, size);
  std::size_t start = 0;
  for (std::size_t nl = s.pending.find('\n'); nl != std::string::npos; nl = s.pending.find('\n', start)) {
    // Whatever the program wrote to the plain stream is older than this line.
    std::fflush(s.base);
    write_all(s.fd, "<" + std::to_string(s.priority) + ">" + s.pending.substr(start, nl + 1 - start));
    start = nl + 1;
  }
  s.pending.erase(0, start);
  return static_cast<ssize_t>(size);
}

}  // namespace

bool is_journal_stream(int fd) {
  const char* env = std::getenv("JOURNAL_STREAM");
  if (env == nullptr) return false;
  unsigned long long device = 0, inode = 0;
  if (std::sscanf(env, "%llu:%llu", &device, &inode) != 2) return false;
  struct stat st{};
  if (fstat(fd, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device && static_cast<unsigned long long>(st.st_ino) == inode;
}

std::FILE* severity_stream(std::FILE* base, Severity severity) {
  static std::map<std::pair<std::FILE*, int>, std::FILE*> streams;
  static std::map<std::FILE*, bool> journal;  // asked once per stream: the answer does not change
  const std::lock_guard lock(streams_mutex());
  auto j = journal.find(base);
  if (j == journal.end()) j = journal.emplace(base, is_journal_stream(fileno(base))).first;
  if (!j->second) return base;
  const auto key = std::make_pair(base, static_cast<int>(severity));
  if (const auto it = streams.find(key); it != streams.end()) return it->second;
  // Kept for the life of the process: lines may be written until exit.
  auto* cookie = new PrefixedStream{base, fileno(base), static_cast<int>(severity), {}};
  cookie_io_functions_t io{};
  io.write = write_prefixed;
  std::FILE* f = fopencookie(cookie, "w", io);
  if (f == nullptr) {
    delete cookie;
    return base;
  }
  std::setvbuf(f, nullptr, _IONBF, 0);  // each line leaves when it ends, in program order
  streams.emplace(key, f);
  return f;
}

void say(std::FILE* base, Severity severity, const char* format, ...) {
  std::FILE* out = severity_stream(base, severity);
  va_list args;
  va_start(args, format);
  std::vfprintf(out, format, args);
  va_end(args);
}

}  // namespace lode::cli
