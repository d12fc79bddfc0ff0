// lode scope's commands: what the page's parameter inputs and swap/promote buttons send.
// Each becomes the very ControlRequest `lode set` / `lode swap` would build and goes over the
// pipeline's DDS command topic through dds::Client::command(), so the pipeline applies the
// same checks (ranges, telemetry.commands.allow_*) and posts the same events; the reply is
// handed back to the page word for word.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "lode/control.hpp"
#include "lode/dds/client.hpp"

namespace lode::cli::scope {

/// One line of a `list` reply ("kf.q_scale [0.01, 100] 1  process noise scale").
struct RuntimeParameter {
  std::string name;  ///< block.param
  bool boolean = false, integer = false;
  double min = 0, max = 0;
  std::string unit, description;
};

/// Parses a `list` reply's value (ControlService's format); lines it cannot read are skipped.
std::vector<RuntimeParameter> parse_parameter_list(const std::string& listing);

/// The page's command (JSON) as a ControlRequest, or nullopt with `error` set.
///   {"kind": "set", "target": "BLOCK.PARAM", "value": "0.3"}   (as lode set BLOCK.PARAM 0.3)
///   {"kind": "get", "target": "BLOCK.PARAM"}                   (as lode set BLOCK.PARAM)
///   {"kind": "list", "block": ""}                              (as lode set --list)
///   {"kind": "swap", "block": "kf", "plugin": "estimator.x", "params": "{...}",
///    "shadow_cycles": N, "cold": false}                        (as lode swap kf estimator.x ...)
///   {"kind": "promote", "shadow": "kf_hybrid"}                 (as lode swap --promote kf_hybrid)
std::optional<ControlRequest> request_from_json(const std::string& body, std::string& error);

class Commands {
 public:
  Commands(dds::Client& client, std::string pipeline, std::chrono::milliseconds timeout)
      : client_(client), pipeline_(std::move(pipeline)), timeout_(timeout) {}

  /// Runs the page's command; the JSON reply {ok, message, value, pipeline, kind}.
  std::string run(const std::string& body);
  /// `list` then `get` of each: [{name, min, max, integer, boolean, unit, description, value}].
  std::string parameters(const std::string& pipeline);

 private:
  /// The pipeline to command: the one named (body or --pipeline), else the only one live.
  std::optional<std::string> pipeline_for(const std::string& named, std::string& error);
  Expected<ControlReply> send(const std::string& pipeline, ControlRequest request);

  dds::Client& client_;
  const std::string pipeline_;
  const std::chrono::milliseconds timeout_;
};

}  // namespace lode::cli::scope
