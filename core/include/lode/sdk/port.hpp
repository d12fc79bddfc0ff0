// Typed ports: fixed-size vectors of doubles with element names and SI units.
//
// A block declares its ports in configure() by passing a port member and a list of
// elements. After every block is configured the pipeline allocates one arena for all
// outputs and resolves each input to a pointer into it, so step() reads and writes plain
// doubles and never looks up a name.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace lode {

struct Element {
  std::string name;  ///< e.g. "x", "theta_z", "a1"
  std::string unit;  ///< SI unit, e.g. "m", "rad", "V", "N", "N*m"; "*" on inputs = any
};

using Elements = std::vector<Element>;

/// Convenience: n elements named prefix0..prefix{n-1} with one unit.
Elements numbered_elements(const std::string& prefix, std::size_t n, const std::string& unit);

/// Storage is owned by the pipeline arena; a block only holds the pointer.
class OutputPort {
 public:
  [[nodiscard]] double* data() const noexcept { return data_; }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  double& operator[](std::size_t i) const noexcept { return data_[i]; }
  [[nodiscard]] bool bound() const noexcept { return data_ != nullptr; }

 private:
  friend class PortBinder;
  double* data_ = nullptr;
  std::size_t size_ = 0;
};

/// Read-only view of the output it is connected to. An optional input that the YAML does
/// not connect stays unbound (connected() is false, data() is nullptr).
class InputPort {
 public:
  [[nodiscard]] const double* data() const noexcept { return data_; }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  double operator[](std::size_t i) const noexcept { return data_[i]; }
  [[nodiscard]] bool connected() const noexcept { return data_ != nullptr; }

 private:
  friend class PortBinder;
  const double* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace lode
