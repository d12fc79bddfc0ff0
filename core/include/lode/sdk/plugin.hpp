// The plugin ABI: one C symbol per shared object returning a versioned descriptor.
//
//   constexpr lode::PortSpec kPorts[] = {
//       {"in", lode::PortDirection::in, "signal to filter, any size"},
//       {"out", lode::PortDirection::out, "filtered signal, the input's elements"},
//   };
//   LODE_PLUGIN(MyBlock, "filter.my_block", lode::PluginKind::filter, "1.0.0",
//               "One-line summary", kParams, kPorts)
//
// The port table is the one declaration of a plugin's ports: configure() binds storage to
// its entries by name, and the loader (and the test harness) refuse a port the table does not
// list, a direction it contradicts, or an unconditional entry that configure() left out.
// `lode plugins` and the catalogue in docs/plugins.md are made from it.
//
// The kind says what the plugin is, and is the first part of its name and the folder it
// lives in under plugins/: source, filter, estimator, controller (blocks), io (a board),
// plant (a PlantModel, possibly also a ProcessModel), sensor (a MeasurementModel).
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

/// 3: estimator state and innovation in Block (hot swap). 4: kinds by role, the port table
/// (PortSpec), Board/Tunables/EstimatorState as optional interfaces beside a cycle-only Block.
/// 5: models hold the element lists they declare (declare_*_elements) instead of overriding
/// virtual accessors.
inline constexpr std::uint32_t kPluginAbiVersion = 6;
inline constexpr const char* kPluginSymbol = "lode_plugin_descriptor";

enum class PluginKind : std::uint32_t {
  source = 0,      ///< a block that makes a reference or test signal
  filter = 1,      ///< a block that filters signals
  estimator = 2,   ///< a block that estimates a state or converts sensor signals to one
  controller = 3,  ///< a block that computes commands
  io = 4,          ///< a board: Block (read phase) and Board (write phase, safe state)
  plant = 5,       ///< a PlantModel (and, when it implements one, a ProcessModel)
  sensor = 6,      ///< a MeasurementModel
};

/// True for the kinds whose plugins create a Block (everything but plant and sensor).
constexpr bool creates_block(PluginKind kind) {
  return kind != PluginKind::plant && kind != PluginKind::sensor;
}

const char* to_string(PluginKind kind);

struct ParamDoc {
  const char* name;           ///< YAML key
  const char* type;           ///< "number", "integer", "bool", "text", "list<number>", "map", ...
  const char* default_value;  ///< nullptr: required
  const char* description;    ///< with units when not in the name
};

enum class PortDirection : std::uint8_t { in = 0, out = 1 };

const char* to_string(PortDirection direction);

/// One entry of a plugin's port table. A name in angle brackets ("<port>") stands for ports
/// whose names come from the configuration (e.g. one per recorded series).
struct PortSpec {
  const char* name;
  PortDirection direction;
  const char* description;
  /// nullptr: configure() always declares this port. Otherwise when it does, in words
  /// ("with an input named feedforward", "when covariance: true").
  const char* condition = nullptr;
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
  const PortSpec* ports;
  std::size_t port_count;
  Component* (*create)();
};

using PluginEntry = const PluginDescriptor* (*)();

/// For a plugin without ports (LODE_PLUGIN(..., kParams, lode::kNoPorts)).
inline constexpr std::nullptr_t kNoPorts = nullptr;

template <typename T, std::size_t N>
constexpr std::size_t table_size(const T (&)[N]) { return N; }
constexpr std::size_t table_size(std::nullptr_t) { return 0; }

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
        ::lode::table_size(ParamsArray),                                                              \
        PortsArray,                                                                          \
        ::lode::table_size(PortsArray),                                                               \
        []() -> ::lode::Component* { return new Class(); }};                                 \
    return &descriptor;                                                                      \
  }
