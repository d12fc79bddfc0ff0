// Common base of everything a plugin creates (blocks and models).
#pragma once

namespace lode {

/// Identity-bearing and owned by the pipeline: never copied or moved.
class Component {
 public:
  Component() = default;
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;
  Component(Component&&) = delete;
  Component& operator=(Component&&) = delete;
  virtual ~Component();
};

}  // namespace lode
