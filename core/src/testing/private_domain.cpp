#include "lode/testing/private_domain.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace lode::testing {

namespace {
constexpr int kFirst = 100;
constexpr int kCount = 130;

int take_domain() {
  const std::string folder = "/tmp/lode-test-domains";
  ::mkdir(folder.c_str(), 01777);  // shared by every user's tests, like /tmp itself
  ::chmod(folder.c_str(), 01777);
  const int start = static_cast<int>(::getpid() % kCount);
  for (int i = 0; i < kCount; ++i) {
    const int domain = kFirst + (start + i) % kCount;
    const std::string path = folder + "/" + std::to_string(domain);
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return domain;  // fd stays open: the lock is ours
    ::close(fd);
  }
  std::fprintf(stderr, "private_dds_domain: all %d test domains are taken\n", kCount);
  std::abort();
}
}  // namespace

int private_dds_domain() {
  static const int domain = take_domain();
  return domain;
}

}  // namespace lode::testing
