// Memory-mapped register window (hal/include/lode/hal/register_window.hpp) over a shared file,
// as the VME emulator provides it: a second mapping sees every write, bounds and alignment are
// checked with messages that name the window.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "lode/hal/register_window.hpp"

namespace {

using lode::hal::RegisterWindow;

struct TempFile {
  TempFile() : path((std::filesystem::temp_directory_path() / ("lode-regwin-" + std::to_string(getpid()))).string()) {}
  ~TempFile() { std::remove(path.c_str()); }
  std::string path;
};

TEST(RegisterWindow, TwoMappingsOfOneFileSeeEachOthersWrites) {
  TempFile f;
  ASSERT_TRUE(RegisterWindow::create_file(f.path, 8192));
  auto board = RegisterWindow::open(f.path, 0x1000, 0x100);  // the emulator's side
  auto host = RegisterWindow::open(f.path, 0x1000, 0x100);   // the backend's side
  ASSERT_TRUE(board) << board.error();
  ASSERT_TRUE(host) << host.error();
  ASSERT_TRUE(host->check(0x10, 4));
  board->write32(0x10, 0xdeadbeef);
  EXPECT_EQ(host->read32(0x10), 0xdeadbeefu);
  host->write16(0x22, 0x1234);
  EXPECT_EQ(board->read16(0x22), 0x1234u);
  EXPECT_EQ(board->read32(0x20), 0x12340000u);  // little endian, as on x86 and VME bridges in LE mode
}

TEST(RegisterWindow, AnOffsetThatIsNotPageAlignedMapsTheRightBytes) {
  TempFile f;
  ASSERT_TRUE(RegisterWindow::create_file(f.path, 3 * 4096));
  auto whole = RegisterWindow::open(f.path, 0, 3 * 4096);
  ASSERT_TRUE(whole) << whole.error();
  whole->write32(0x1230, 0x01020304);
  auto window = RegisterWindow::open(f.path, 0x1200, 0x40);
  ASSERT_TRUE(window) << window.error();
  EXPECT_EQ(window->read32(0x30), 0x01020304u);
  RegisterWindow moved = std::move(*window);
  EXPECT_FALSE(window->mapped());
  EXPECT_EQ(moved.read32(0x30), 0x01020304u);
}

TEST(RegisterWindow, ErrorsNameTheWindowTheRegisterAndWhy) {
  TempFile f;
  ASSERT_TRUE(RegisterWindow::create_file(f.path, 4096));
  auto short_file = RegisterWindow::open(f.path, 0x800, 0x1000);
  ASSERT_FALSE(short_file);
  EXPECT_NE(short_file.error().find(f.path + " @ 0x800 (+4096 bytes): " + f.path + " is only 4096 bytes long"),
            std::string::npos)
      << short_file.error();
  auto missing = RegisterWindow::open(f.path + ".none", 0, 16);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("cannot open"), std::string::npos) << missing.error();

  auto w = RegisterWindow::open(f.path, 0x100, 0x40);
  ASSERT_TRUE(w) << w.error();
  EXPECT_TRUE(w->check(0x3c, 4));
  const auto outside = w->check(0x3e, 4);
  ASSERT_FALSE(outside);
  EXPECT_NE(outside.message().find("@ 0x100 (+64 bytes): register at 0x3e (4 bytes) lies outside the window"),
            std::string::npos)
      << outside.message();
  const auto huge = w->check(static_cast<std::size_t>(-2), 4);  // no wrap-around
  EXPECT_FALSE(huge);
  const auto misaligned = w->check(0x2, 4);
  ASSERT_FALSE(misaligned);
  EXPECT_NE(misaligned.message().find("is not 4-byte aligned"), std::string::npos) << misaligned.message();
  EXPECT_FALSE(w->check(0x0, 3));
}

}  // namespace
