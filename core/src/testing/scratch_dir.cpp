#include "lode/sdk/testing/scratch_dir.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <system_error>

namespace lode::testing {
namespace {

struct ScratchDir {
  std::string path;
  pid_t owner = ::getpid();
  ScratchDir() {
    std::error_code ignored;
    path = (std::filesystem::temp_directory_path(ignored) / ("lode-test-" + std::to_string(::getpid()))).string();
    ::mkdir(path.c_str(), 0700);
  }
  // Runs at normal process exit (gtest's main returning, or exit()); a test killed by a
  // signal is the one case that leaves the folder. A forked child that exits must not take
  // its parent's files with it.
  ~ScratchDir() {
    if (::getpid() != owner) return;
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};

}  // namespace

const std::string& scratch_dir() {
  static const ScratchDir dir;
  return dir.path;
}

std::string scratch_path(const std::string& name) { return scratch_dir() + "/" + name; }

}  // namespace lode::testing
