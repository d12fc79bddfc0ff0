// Internal: binds declared ports to arena storage (the only writer of their pointers).
#pragma once

#include "lode/sdk/port.hpp"

namespace lode {

class PortBinder {
 public:
  static void bind(OutputPort& port, double* data, std::size_t size) {
    port.data_ = data;
    port.size_ = size;
  }
  static void bind(InputPort& port, const double* data, std::size_t size) {
    port.data_ = data;
    port.size_ = size;
  }
};

}  // namespace lode
