#include "lode/hal/register_window.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

namespace lode::hal {

RegisterWindow::~RegisterWindow() { unmap(); }

RegisterWindow::RegisterWindow(RegisterWindow&& other) noexcept { *this = std::move(other); }

RegisterWindow& RegisterWindow::operator=(RegisterWindow&& other) noexcept {
  if (this == &other) return *this;
  unmap();
  path_ = std::move(other.path_);
  offset_ = other.offset_;
  length_ = other.length_;
  base_ = std::exchange(other.base_, nullptr);
  mapping_ = std::exchange(other.mapping_, nullptr);
  mapping_length_ = std::exchange(other.mapping_length_, 0);
  fd_ = std::exchange(other.fd_, -1);
  return *this;
}

void RegisterWindow::unmap() noexcept {
  if (mapping_) munmap(mapping_, mapping_length_);
  if (fd_ >= 0) close(fd_);
  mapping_ = nullptr;
  base_ = nullptr;
  mapping_length_ = 0;
  fd_ = -1;
}

std::string RegisterWindow::describe() const {
  return path_ + " @ " + hex(offset_) + " (+" + std::to_string(length_) + " bytes)";
}

Status RegisterWindow::create_file(const std::string& path, std::size_t size) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return Status::error("cannot create " + path + ": " + std::strerror(errno));
  struct stat st {};
  Status result;
  if (fstat(fd, &st) != 0) {
    result = Status::error("cannot stat " + path + ": " + std::strerror(errno));
  } else if (static_cast<std::size_t>(st.st_size) < size && ftruncate(fd, static_cast<off_t>(size)) != 0) {
    result = Status::error("cannot size " + path + " to " + std::to_string(size) + " bytes: " + std::strerror(errno));
  }
  close(fd);
  return result;
}

Expected<RegisterWindow> RegisterWindow::open(const std::string& path, std::uint64_t offset, std::size_t length) {
  const std::string where = path + " @ " + hex(offset) + " (+" + std::to_string(length) + " bytes)";
  if (length == 0) return Status::error("register window " + where + ": length must be > 0");
  const int fd = ::open(path.c_str(), O_RDWR | O_SYNC | O_CLOEXEC);
  if (fd < 0)
    return Status::error("register window " + where + ": cannot open " + path + ": " + std::strerror(errno) +
                         (errno == EACCES ? " (UIO and /dev/mem need the device's group or root)" : ""));
  struct stat st {};
  if (fstat(fd, &st) != 0) {
    const int e = errno;
    close(fd);
    return Status::error("register window " + where + ": cannot stat: " + std::strerror(e));
  }
  // A regular file (an emulator's window) must hold the whole window: a mapping past its end
  // would raise SIGBUS on the first access instead of an error here.
  if (S_ISREG(st.st_mode) && static_cast<std::uint64_t>(st.st_size) < offset + length) {
    close(fd);
    return Status::error("register window " + where + ": " + path + " is only " + std::to_string(st.st_size) +
                         " bytes long (is the emulator running?)");
  }
  const auto page = static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
  const std::uint64_t map_start = offset / page * page;
  const std::size_t lead = static_cast<std::size_t>(offset - map_start);
  const std::size_t map_length = lead + length;
  void* m = mmap(nullptr, map_length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, static_cast<off_t>(map_start));
  if (m == MAP_FAILED) {
    const int e = errno;
    close(fd);
    return Status::error("register window " + where + ": mmap failed: " + std::strerror(e));
  }
  RegisterWindow w;
  w.path_ = path;
  w.offset_ = offset;
  w.length_ = length;
  w.mapping_ = m;
  w.mapping_length_ = map_length;
  w.base_ = static_cast<volatile std::uint8_t*>(m) + lead;
  w.fd_ = fd;
  return w;
}

Status RegisterWindow::check(std::size_t byte_offset, std::size_t width) const {
  if (!mapped()) return Status::error("register window not mapped");
  if (width != 1 && width != 2 && width != 4 && width != 8)
    return Status::error(describe() + ": register width " + std::to_string(width) + " bytes (1, 2, 4 or 8)");
  if (byte_offset > length_ || width > length_ - byte_offset)
    return Status::error(describe() + ": register at " + hex(byte_offset) + " (" + std::to_string(width) +
                         " bytes) lies outside the window");
  // Natural alignment in the address space, not only within the window: a misaligned access
  // is split (or faults) on the bus.
  if ((offset_ + byte_offset) % width != 0)
    return Status::error(describe() + ": register at " + hex(byte_offset) + " is not " + std::to_string(width) +
                         "-byte aligned");
  return {};
}

}  // namespace lode::hal
