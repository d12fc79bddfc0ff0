// Internal: a command on the wire and the ControlService request, both ways: the client
// writes a request as a Command (command_message), the bridge reads a Command as a request
// (command_request). Side by side so that a field added to one direction is seen missing
// from the other. command_request is also what the fuzzer feeds arbitrary samples, so that
// what is fuzzed is what runs.
#pragma once

#include <cstdint>
#include <string>

#include "lode/control.hpp"
#include "lode_msgs.h"

namespace lode::dds::detail {

/// Every field as sent; `client` is the identity the bridge vouches for (the discovered
/// participant name when access is checked, else what the sender declares).
inline ControlRequest command_request(const lode::msg::Command& command, const std::string& client) {
  ControlRequest request;
  request.id = command.id();
  request.kind = command.kind();
  request.block = command.block();
  request.name = command.name();
  request.value = command.value();
  request.plugin = command.plugin();
  request.client = client;
  return request;
}

/// What a client sends: every field of `request` but its id, which stays with the caller;
/// on the wire the command carries `wire_id`, unique to this client.
inline lode::msg::Command command_message(const ControlRequest& request, const std::string& client,
                                          std::uint64_t wire_id) {
  lode::msg::Command command;
  command.client(client);
  command.id(wire_id);
  command.kind(request.kind);
  command.block(request.block);
  command.name(request.name);
  command.value(request.value);
  command.plugin(request.plugin);
  return command;
}

}  // namespace lode::dds::detail
