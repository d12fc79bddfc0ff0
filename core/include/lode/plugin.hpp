// The plugin ABI: one C symbol per shared object returning a versioned descriptor.
//
//   LODE_PLUGIN(MyBlock, "filter.my_block", lode::PluginKind::block, "1.0.0",
//               "One-line summary", kParams, kPorts)
//
// The loader checks abi_version and descriptor_size before touching anything else and
// refuses a mismatch with a message naming the file and both versions. Plugins are built
// against the same SDK headers with the same compiler (C++ classes cross the boundary);
// kPluginAbiVersion changes whenever Block, the models or this struct change layout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iterator>

#include "lode/sdk/component.hpp"

namespace lode {

inline constexpr std::uint32_t kPluginAbiVersion = 3;  // 3: estimator state and innovation in Block (hot swap)
inline constexpr const char* kPluginSymbol = "lode_plugin_descriptor";

enum class PluginKind : std::uint32_t {
  block = 0,   ///< sensor conversion, filter, estimator, controller, source
  io = 1,      ///< a board: read phase and write phase
  plant = 2,   ///< PlantModel
  sensor = 3,  ///< MeasurementModel
  process = 4, ///< ProcessModel only (a plant plugin may also implement ProcessModel)
};

const char* to_string(PluginKind kind);

struct ParamDoc {
  const char* name;           ///< YAML key
  const char* type;           ///< "number", "integer", "bool", "text", "list<number>", "map", ...
  const char* default_value;  ///< nullptr: required
  const char* description;    ///< with units when not in the name
};

struct PortDoc {
  const char* name;
  const char* direction;  ///< "in" or "out"
  const char* description;
};

struct PluginDescriptor {
  std::uint32_t abi_version;
  std::uint32_t descriptor_size;
  const char* name;
  PluginKind kind;
  const char* version;
  const char* summary;
  const ParamDoc* params;
  std::size_t param_count;
  const PortDoc* ports;
  std::size_t port_count;
  Component* (*create)();
};

using PluginEntry = const PluginDescriptor* (*)();

}  // namespace lode

#define LODE_PLUGIN(Class, Name, Kind, Version, Summary, ParamsArray, PortsArray)             \
  extern "C" __attribute__((visibility("default"))) const ::lode::PluginDescriptor*         \
  lode_plugin_descriptor() {                                                                 \
    static const ::lode::PluginDescriptor descriptor{                                        \
        ::lode::kPluginAbiVersion,                                                           \
        static_cast<std::uint32_t>(sizeof(::lode::PluginDescriptor)),                        \
        Name,                                                                                \
        Kind,                                                                                \
        Version,                                                                             \
        Summary,                                                                             \
        ParamsArray,                                                                         \
        std::size(ParamsArray),                                                              \
        PortsArray,                                                                          \
        std::size(PortsArray),                                                               \
        []() -> ::lode::Component* { return new Class(); }};                                 \
    return &descriptor;                                                                      \
  }
