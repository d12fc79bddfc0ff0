// The shared-memory files of Fast DDS processes that ended without closing their participant
// are removed, and nothing else is (core/dds/src/shared_memory_leftovers.hpp). In a folder of
// the test's own, laid out as Fast DDS 2.x lays out /dev/shm; "alive" is a lock file another
// open file description holds flock()ed, as a live owner does.
#include "shared_memory_leftovers.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <string>
#include <vector>

#include "lode/sdk/testing/scratch_dir.hpp"

namespace {

namespace fs = std::filesystem;
using lode::dds::detail::remove_dead_shared_memory;

class SharedMemoryLeftovers : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = lode::testing::scratch_path(::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    for (int fd : held_) ::close(fd);
  }

  /// A file of `bytes` bytes, last modified `age_s` seconds ago.
  void make(const std::string& name, std::size_t bytes = 0, int age_s = 60) {
    const std::string path = dir_ + "/" + name;
    std::ofstream(path) << std::string(bytes, 'x');
    const timespec times[2] = {{::time(nullptr) - age_s, 0}, {::time(nullptr) - age_s, 0}};
    ASSERT_EQ(::utimensat(AT_FDCWD, path.c_str(), times, 0), 0) << path;
  }
  /// The lock file `name` held, as its living owner holds it.
  void hold(const std::string& name) {
    const int fd = ::open((dir_ + "/" + name).c_str(), O_RDONLY | O_CLOEXEC);
    ASSERT_GE(fd, 0) << name;
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0) << name;
    held_.push_back(fd);
  }
  [[nodiscard]] bool present(const std::string& name) const { return fs::exists(dir_ + "/" + name); }

  std::string dir_;
  std::vector<int> held_;
};

TEST_F(SharedMemoryLeftovers, ADeadSegmentGoesWithItsLock) {
  make("fastrtps_0123456789abcdef", 8192);
  make("fastrtps_0123456789abcdef_el");
  const auto removed = remove_dead_shared_memory(dir_, std::chrono::seconds(2));
  EXPECT_EQ(removed.segments, 1U);
  EXPECT_EQ(removed.ports, 0U);
  EXPECT_GE(removed.bytes, 8192U) << "the memory the segment held";
  EXPECT_FALSE(present("fastrtps_0123456789abcdef"));
  EXPECT_FALSE(present("fastrtps_0123456789abcdef_el"));
}

TEST_F(SharedMemoryLeftovers, ALiveSegmentStays) {
  make("fastrtps_a1b2c3d4e5f60718", 4096);
  make("fastrtps_a1b2c3d4e5f60718_el");
  hold("fastrtps_a1b2c3d4e5f60718_el");
  const auto removed = remove_dead_shared_memory(dir_, std::chrono::seconds(2));
  EXPECT_EQ(removed.segments, 0U);
  EXPECT_TRUE(present("fastrtps_a1b2c3d4e5f60718"));
  EXPECT_TRUE(present("fastrtps_a1b2c3d4e5f60718_el"));
}

TEST_F(SharedMemoryLeftovers, ALockJustCreatedIsNotJudgedYet) {
  // Fast DDS creates the lock file, then locks it: between the two it looks dead.
  make("fastrtps_ffffffffffffffff", 4096, /*age_s=*/0);
  make("fastrtps_ffffffffffffffff_el", 0, /*age_s=*/0);
  EXPECT_EQ(remove_dead_shared_memory(dir_, std::chrono::seconds(2)).segments, 0U);
  EXPECT_TRUE(present("fastrtps_ffffffffffffffff"));
  EXPECT_TRUE(present("fastrtps_ffffffffffffffff_el"));
}

TEST_F(SharedMemoryLeftovers, ADeadPortGoesWithItsSemaphoreALiveOneStays) {
  make("fastrtps_port1024", 2048);
  make("fastrtps_port1024_el");
  make("sem.fastrtps_port1024_mutex", 32);
  make("fastrtps_port7413", 2048);
  make("fastrtps_port7413_sl");
  make("sem.fastrtps_port7413_mutex", 32);
  hold("fastrtps_port7413_sl");
  const auto removed = remove_dead_shared_memory(dir_, std::chrono::seconds(2));
  EXPECT_EQ(removed.ports, 1U);
  EXPECT_EQ(removed.segments, 0U);
  for (const char* gone : {"fastrtps_port1024", "fastrtps_port1024_el", "sem.fastrtps_port1024_mutex"})
    EXPECT_FALSE(present(gone)) << gone;
  for (const char* kept : {"fastrtps_port7413", "fastrtps_port7413_sl", "sem.fastrtps_port7413_mutex"})
    EXPECT_TRUE(present(kept)) << kept;
}

TEST_F(SharedMemoryLeftovers, OtherFilesAreNotTouched) {
  // Names that only look like Fast DDS's: another length or alphabet of id, no lock suffix,
  // a lock file without the prefix, lodestone's own port claims, a port without a lock file.
  const std::vector<std::string> others = {
      "fastrtps_0123456789abcde_el",  "fastrtps_0123456789ABCDEF_el", "fastrtps_0123456789abcdef_xl",
      "something_0123456789abcdef_el", "lode_shm_port1024_claim",      "fastrtps_port60161",
      "sem.fastrtps_port60161_mutex",  "fastrtps_portx1_el",           "fastrtps_0123456789abcdef"};
  for (const auto& name : others) make(name, 16);
  const auto removed = remove_dead_shared_memory(dir_, std::chrono::seconds(2));
  EXPECT_EQ(removed.segments + removed.ports, 0U);
  for (const auto& name : others) EXPECT_TRUE(present(name)) << name;
}

TEST_F(SharedMemoryLeftovers, ASymlinkNamedLikeALockIsNotFollowed) {
  make("target_file", 16);
  ASSERT_EQ(::symlink((dir_ + "/target_file").c_str(), (dir_ + "/fastrtps_0000000000000000_el").c_str()), 0);
  make("fastrtps_0000000000000000", 16);
  EXPECT_EQ(remove_dead_shared_memory(dir_, std::chrono::seconds(0)).segments, 0U);
  EXPECT_TRUE(present("target_file"));
  EXPECT_TRUE(present("fastrtps_0000000000000000"));
}

TEST_F(SharedMemoryLeftovers, AMissingFolderRemovesNothing) {
  const auto removed = remove_dead_shared_memory(dir_ + "/absent", std::chrono::seconds(2));
  EXPECT_EQ(removed.segments + removed.ports, 0U);
}

}  // namespace
