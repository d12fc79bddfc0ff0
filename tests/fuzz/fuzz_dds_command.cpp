// libFuzzer target: a command as it arrives over DDS, from any participant on the domain.
// The bytes are deserialized as the Command type (CDR, as Fast DDS hands it to the bridge),
// then every field goes through the ControlService of a small live pipeline exactly as the
// bridge passes it (set, get, list, status, swap and record without their handlers). Beyond
// "no crash": every request gets a reply with a message, and a refused `set` changes nothing.
#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include "lode/control.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"
#include "command_request.hpp"
#include "lode_msgs.h"

namespace {

const char* kPipeline = R"(pipeline: fuzz
rate_hz: 1000
blocks:
  wobble:
    plugin: source.sine
    names: [x]
    units: [m]
    amplitude: [1.0e-3]
    frequency_hz: [5]
)";

struct Rig {
  lode::PluginRegistry registry;
  lode::EventLog events;
  std::unique_ptr<lode::Pipeline> pipeline;
  std::unique_ptr<lode::ControlService> control;
  Rig() {
    lode::Diagnostics diag;
    pipeline = lode::Pipeline::load_text(kPipeline, "fuzz.yaml", registry, diag);
    if (!pipeline) std::abort();  // LODE_PLUGIN_PATH must point at the built plugins
    control = std::make_unique<lode::ControlService>(*pipeline, events);
  }
};

Rig& rig() {
  static Rig r;
  return r;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lode::msg::Command command;
  {
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(const_cast<std::uint8_t*>(data)), size);
    eprosima::fastcdr::Cdr cdr(buffer, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN, eprosima::fastcdr::Cdr::DDS_CDR);
    try {
      cdr.read_encapsulation();
      command.deserialize(cdr);
    } catch (const eprosima::fastcdr::exception::Exception&) {
      return 0;  // Fast DDS drops a sample that does not deserialize
    }
  }
  const lode::ControlRequest request = lode::dds::detail::command_request(command, command.client());
  Rig& r = rig();
  lode::ControlRequest get;
  get.kind = "get";
  get.block = "wobble";
  get.name = request.name;
  const auto before = r.control->handle(get, std::chrono::milliseconds(100));
  const auto reply = r.control->handle(request, std::chrono::milliseconds(100));
  if (reply.message.empty()) std::abort();
  if (request.kind == "set" && !reply.ok && before.ok) {
    const auto after = r.control->handle(get, std::chrono::milliseconds(100));
    if (!after.ok || after.value != before.value) std::abort();  // a refused set changed the value
  }
  return 0;
}
