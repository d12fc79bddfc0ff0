// A plugin built against a different (future) ABI version.
#include "lode/sdk/plugin.hpp"

extern "C" __attribute__((visibility("default"))) const lode::PluginDescriptor* lode_plugin_descriptor() {
  static const lode::PluginDescriptor d{lode::kPluginAbiVersion + 1, sizeof(lode::PluginDescriptor),
                                        "filter.from_the_future", lode::PluginKind::block, "9.0.0",
                                        "wrong ABI", nullptr, 0, nullptr, 0, nullptr};
  return &d;
}
