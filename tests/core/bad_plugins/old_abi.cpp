// A plugin built against the previous SDK (ABI 5: the models had no evaluate_points() or
// propagate_points(), so their virtual tables are laid out differently; the descriptor had
// today's fields). Only the first two fields are read.
#include <cstddef>
#include <cstdint>

namespace {
struct DescriptorAbi5 {
  std::uint32_t abi_version;
  std::uint32_t descriptor_size;
  const char* name;
  std::uint32_t kind;
  const char* version;
  const char* summary;
  const void* params;
  std::size_t param_count;
  const void* ports;
  std::size_t port_count;
  void* (*create)();
};
}  // namespace

extern "C" __attribute__((visibility("default"))) const void* lode_plugin_descriptor() {
  static const DescriptorAbi5 d{5, sizeof(DescriptorAbi5), "filter.from_the_past", 0, "1.0.0",
                                "built for ABI 5", nullptr, 0, nullptr, 0, nullptr};
  return &d;
}
