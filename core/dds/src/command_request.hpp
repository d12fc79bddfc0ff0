// Internal: a command as it arrives over DDS, as the ControlService request it becomes.
// One function, used by the bridge and by the fuzzer that feeds it arbitrary samples, so
// that what is fuzzed is what runs.
#pragma once

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

}  // namespace lode::dds::detail
