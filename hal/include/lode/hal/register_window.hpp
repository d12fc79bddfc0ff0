// A memory-mapped register window (hal/): the registers of a board reached through
// a UIO device (/dev/uioN, map 0), a physical-address window of /dev/mem behind a VME bridge,
// or a shared-memory file that an emulator maps too.
//
//   auto w = RegisterWindow::open("/dev/shm/lode-vme0", 0x0, 0x1000);   // path, offset, length
//   if (!w) ...w.error() names the path, the offset and why
//   if (auto st = w->check(0x40, 4); !st) ...       // at configure time: in range, aligned
//   std::uint32_t status = w->read32(0x40);          // RT path: volatile, no checks, noexcept
//
// The offset need not be page aligned (a /dev/mem window rarely is): the mapping starts at
// the page boundary below it and the window is the requested part. Every register a backend
// will touch is checked once with check(); read32/write32 then do only the volatile access,
// so the compiler neither caches nor reorders them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "lode/sdk/status.hpp"

namespace lode::hal {

/// An offset or register value as "0x1f4", for messages about windows and registers.
inline std::string hex(std::uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%llx", static_cast<unsigned long long>(v));
  return buf;
}

class RegisterWindow {
 public:
  RegisterWindow() = default;
  ~RegisterWindow();
  RegisterWindow(RegisterWindow&& other) noexcept;
  RegisterWindow& operator=(RegisterWindow&& other) noexcept;
  RegisterWindow(const RegisterWindow&) = delete;
  RegisterWindow& operator=(const RegisterWindow&) = delete;

  /// Map `length` bytes at `offset` of `path` read-write and shared. A regular file must
  /// already be at least offset + length long (an emulator creates it; see create_file).
  static Expected<RegisterWindow> open(const std::string& path, std::uint64_t offset, std::size_t length);
  /// For emulators and tests: create (or extend) a regular file of `size` bytes, zero-filled.
  static Status create_file(const std::string& path, std::size_t size);

  /// A register of `width` bytes (1, 2, 4 or 8) at `byte_offset` lies in the window and is
  /// naturally aligned; else the error names the window, the offset and the width.
  [[nodiscard]] Status check(std::size_t byte_offset, std::size_t width) const;

  [[nodiscard]] std::uint32_t read32(std::size_t byte_offset) const noexcept { return *at<std::uint32_t>(byte_offset); }
  void write32(std::size_t byte_offset, std::uint32_t value) noexcept { *at<std::uint32_t>(byte_offset) = value; }
  [[nodiscard]] std::uint16_t read16(std::size_t byte_offset) const noexcept { return *at<std::uint16_t>(byte_offset); }
  void write16(std::size_t byte_offset, std::uint16_t value) noexcept { *at<std::uint16_t>(byte_offset) = value; }

  [[nodiscard]] bool mapped() const noexcept { return base_ != nullptr; }
  [[nodiscard]] std::size_t length() const noexcept { return length_; }
  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  [[nodiscard]] std::uint64_t offset() const noexcept { return offset_; }
  /// "path @ 0xOFFSET (+LENGTH bytes)", for messages.
  [[nodiscard]] std::string describe() const;

 private:
  template <typename T>
  [[nodiscard]] volatile T* at(std::size_t byte_offset) const noexcept {
    return static_cast<volatile T*>(static_cast<volatile void*>(base_ + byte_offset));
  }
  void unmap() noexcept;

  std::string path_;
  std::uint64_t offset_ = 0;
  std::size_t length_ = 0;
  volatile std::uint8_t* base_ = nullptr;  // first byte of the window
  void* mapping_ = nullptr;                // page-aligned start of the mapping
  std::size_t mapping_length_ = 0;
  int fd_ = -1;
};

}  // namespace lode::hal
