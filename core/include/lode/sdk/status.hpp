// Errors as values for everything that runs off the real-time thread.
//
// configure()/activate() and the loaders return Status or Expected<T>; nothing in the
// configuration path throws across a plugin boundary. step() returns a StepStatus
// (see block.hpp) and never a Status, because a Status may own a heap-allocated message.
#pragma once

#include <string>
#include <utility>
#include <variant>

namespace lode {

class Status {
 public:
  Status() = default;  // success
  static Status ok() { return {}; }
  static Status error(std::string message) { return Status(std::move(message)); }

  [[nodiscard]] bool is_ok() const { return !failed_; }
  explicit operator bool() const { return !failed_; }
  [[nodiscard]] const std::string& message() const { return message_; }

 private:
  explicit Status(std::string message) : failed_(true), message_(std::move(message)) {}
  bool failed_ = false;
  std::string message_;
};

/// A value or the reason there is none (std::expected is C++23; g++ 12 builds C++20).
template <typename T>
class Expected {
 public:
  Expected(T value) : v_(std::move(value)) {}  // NOLINT: implicit by design
  Expected(Status error) : v_(std::move(error)) {}  // NOLINT: must be a failed Status

  [[nodiscard]] bool has_value() const { return v_.index() == 0; }
  explicit operator bool() const { return has_value(); }
  T& value() { return std::get<0>(v_); }
  const T& value() const { return std::get<0>(v_); }
  T& operator*() { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  const T& operator*() const { return value(); }
  [[nodiscard]] const std::string& error() const { return std::get<1>(v_).message(); }
  [[nodiscard]] Status status() const { return has_value() ? Status::ok() : std::get<1>(v_); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace lode
