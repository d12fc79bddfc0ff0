// The figures behind "needs about N of memory; this process has M left": /proc/meminfo and a
// control group's limit, usage and droppable page cache, as the kernel writes them.
#include "lode/host_memory.hpp"

#include <gtest/gtest.h>

namespace {

TEST(HostMemory, AvailableIsMemAvailablePlusSwapFree) {
  const char* meminfo =
      "MemTotal:       24684148 kB\n"
      "MemFree:        19935016 kB\n"
      "MemAvailable:   23571764 kB\n"
      "SwapTotal:       2097148 kB\n"
      "SwapFree:        1048576 kB\n";
  EXPECT_EQ(lode::meminfo_available_bytes(meminfo), (23571764ULL + 1048576ULL) * 1024);
  // No swap line: MemAvailable alone; no MemAvailable (kernels before 3.14): unknown.
  EXPECT_EQ(lode::meminfo_available_bytes("MemAvailable:  100 kB\n"), 100ULL * 1024);
  EXPECT_EQ(lode::meminfo_available_bytes("MemFree: 100 kB\nSwapFree: 5 kB\n"), std::nullopt);
  // A key that only starts like another is not it.
  EXPECT_EQ(lode::meminfo_available_bytes("MemAvailableX: 7 kB\nMemAvailable: 3 kB\n"), 3ULL * 1024);
  EXPECT_EQ(lode::meminfo_available_bytes("MemAvailable: lots kB\n"), std::nullopt);
}

TEST(HostMemory, CgroupHeadroomIsLimitLessUsageLessDroppableCache) {
  // cgroup v2: memory.max, memory.current, memory.stat.
  EXPECT_EQ(lode::cgroup_headroom_bytes("209715200\n", "10000000\n", "anon 1\nfile 5000000\n"), 199715200ULL);
  EXPECT_EQ(lode::cgroup_headroom_bytes("209715200\n", "110000000\n", "inactive_file 100000000\n"), 199715200ULL);
  EXPECT_EQ(lode::cgroup_headroom_bytes("max\n", "10000000\n", ""), std::nullopt);
  // cgroup v1: no limit is a page-rounded 2^63 - 1; its stat says total_inactive_file.
  EXPECT_EQ(lode::cgroup_headroom_bytes("9223372036854771712\n", "4415422464\n", ""), std::nullopt);
  EXPECT_EQ(lode::cgroup_headroom_bytes("1000\n", "900\n", "total_inactive_file 300\n"), 400ULL);
  // The active file pages are droppable too (a file just written and read back is active).
  EXPECT_EQ(lode::cgroup_headroom_bytes("1000\n", "900\n", "inactive_file 100\nactive_file 200\n"), 400ULL);
  EXPECT_EQ(lode::cgroup_headroom_bytes("1000\n", "900\n", "total_active_file 300\n"), 400ULL);
  // Over the limit (it happens, briefly): nothing left, not a wrapped-around huge number.
  EXPECT_EQ(lode::cgroup_headroom_bytes("1000\n", "1500\n", ""), 0ULL);
  EXPECT_EQ(lode::cgroup_headroom_bytes("1000\n", "", ""), std::nullopt);
  EXPECT_EQ(lode::cgroup_headroom_bytes("", "10\n", ""), std::nullopt);
}

TEST(HostMemory, BytesReadAsAPersonWouldWriteThem) {
  EXPECT_EQ(lode::format_bytes(386623476), "387 MB");
  EXPECT_EQ(lode::format_bytes(2300000000ULL), "2.3 GB");
  EXPECT_EQ(lode::format_bytes(512000), "512 kB");
}

TEST(HostMemory, ThisMachineReportsSomething) {
  // Every Linux since 3.14 has MemAvailable: the check is never silently off here.
  const auto available = lode::available_memory_bytes();
  ASSERT_TRUE(available.has_value());
  EXPECT_GT(*available, 0ULL);
}

}  // namespace
