#include "lode/testing/private_domain.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstdint>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace lode::testing {

namespace {
constexpr int kFirst = 100;
constexpr int kCount = 130;

/// Fast DDS's default port mapping (RTPS 9.6.1.1): the metatraffic unicast port of
/// participant p on domain d is 7400 + 250 d + 10 + 2 p, its user unicast port one above. A
/// participant of anyone else (another user's `lode run`, a lab tool on domain d) holds one of
/// the first few of these over UDP, or, with the shared-memory transport, a port file in
/// /dev/shm. The lock files only coordinate tests; this sees everything else.
bool domain_in_use(int domain) {
  for (int participant = 0; participant < 8; ++participant) {
    const int port = 7400 + 250 * domain + 10 + 2 * participant;
    const std::string shm = "/dev/shm/fastrtps_port" + std::to_string(port);
    struct stat st {};
    if (::stat(shm.c_str(), &st) == 0) return true;
    const int s = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s < 0) continue;
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_ANY);
    const bool taken = ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 && errno == EADDRINUSE;
    ::close(s);
    if (taken) return true;
  }
  return false;
}

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
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      if (!domain_in_use(domain)) return domain;  // fd stays open: the lock is ours
      ::flock(fd, LOCK_UN);
    }
    ::close(fd);
  }
  std::fprintf(stderr, "private_dds_domain: all %d test domains are taken\n", kCount);
  std::abort();
}
}  // namespace

int private_dds_domain() {
  static const int domain = take_domain();
  std::fprintf(stderr, "[test] private DDS domain %d\n", domain);
  return domain;
}

int another_private_dds_domain() { return take_domain(); }

}  // namespace lode::testing
