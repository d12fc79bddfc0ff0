#include "scope_commands.hpp"

#include <algorithm>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lode/hot_swap.hpp"

namespace lode::cli::scope {

using nlohmann::json;

std::vector<RuntimeParameter> parse_parameter_list(const std::string& listing) {
  // ControlService writes "block.param RANGE  description" with RANGE "true|false" or
  // "[min, max][ integer][ unit]": the two spaces end the range.
  std::vector<RuntimeParameter> out;
  std::istringstream lines(listing);
  std::string line;
  while (std::getline(lines, line)) {
    const auto space = line.find(' ');
    if (space == std::string::npos || line.find('.') > space) continue;
    RuntimeParameter p;
    p.name = line.substr(0, space);
    std::string rest = line.substr(space + 1);
    const auto gap = rest.find("  ");
    std::string range = rest.substr(0, gap);
    if (gap != std::string::npos) p.description = rest.substr(gap + 2);
    if (range == "true|false") {
      p.boolean = true;
      p.max = 1;
    } else {
      const auto close = range.find(']');
      const auto comma = range.find(',');
      if (range.empty() || range[0] != '[' || close == std::string::npos || comma == std::string::npos || comma > close)
        continue;
      p.min = std::strtod(range.c_str() + 1, nullptr);
      p.max = std::strtod(range.c_str() + comma + 1, nullptr);
      std::string after = close + 1 < range.size() ? range.substr(close + 2) : "";
      if (after.rfind("integer", 0) == 0) {
        p.integer = true;
        after = after.size() > 7 ? after.substr(8) : "";
      }
      p.unit = after;
    }
    out.push_back(std::move(p));
  }
  return out;
}

namespace {

std::string text_field(const json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return "";
  return it->is_string() ? it->get<std::string>() : it->dump();
}

/// Splits "BLOCK.PARAM" as lode set does: both parts non-empty.
bool split_target(const std::string& target, ControlRequest& r, std::string& error) {
  const auto dot = target.find('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == target.size()) {
    error = "expected BLOCK.PARAM, got '" + target + "'";
    return false;
  }
  r.block = target.substr(0, dot);
  r.name = target.substr(dot + 1);
  return true;
}

}  // namespace

std::optional<ControlRequest> request_from_json(const std::string& body, std::string& error) {
  const json j = json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    error = "the command is not a JSON object";
    return std::nullopt;
  }
  const std::string kind = text_field(j, "kind");
  ControlRequest r;
  if (kind == "set" || kind == "get") {
    if (!split_target(text_field(j, "target"), r, error)) return std::nullopt;
    r.kind = kind;
    if (kind == "set") {
      r.value = text_field(j, "value");
      if (r.value.empty()) {
        error = "set: no value";
        return std::nullopt;
      }
    }
  } else if (kind == "list") {
    r.kind = "list";
    r.block = text_field(j, "block");
  } else if (kind == "swap") {
    // What lode swap sends (swap_command).
    SwapRequest s;
    s.block = text_field(j, "block");
    s.plugin = text_field(j, "plugin");
    s.params = text_field(j, "params");
    if (s.block.empty() || s.plugin.empty()) {
      error = "swap: needs a block and a plugin";
      return std::nullopt;
    }
    if (j.contains("shadow_cycles") && j["shadow_cycles"].is_number_integer()) {
      const long long cycles = j["shadow_cycles"].get<long long>();
      if (cycles > 0) s.shadow_cycles = static_cast<std::uint32_t>(std::min<long long>(cycles, 100000000));
    }
    s.warm_start = !j.value("cold", false);
    r = swap_command(s);
  } else if (kind == "promote") {
    // What lode swap --promote SHADOW sends.
    const std::string shadow = text_field(j, "shadow");
    if (shadow.empty()) {
      error = "promote: no shadow named";
      return std::nullopt;
    }
    r = promote_command(shadow);
  } else {
    error = "unknown command kind '" + kind + "' (set, get, list, swap, promote)";
    return std::nullopt;
  }
  return r;
}

std::optional<std::string> Commands::pipeline_for(const std::string& named, std::string& error) {
  if (!named.empty()) return named;
  if (!pipeline_.empty()) return pipeline_;
  const auto live = client_.pipelines(std::chrono::milliseconds(0));
  if (live.size() == 1) return live[0];
  if (live.empty()) {
    error = "no pipeline is publishing on this domain";
  } else {
    // Never a guessed pipeline, as lode set: the page names one when several are live.
    error = "several pipelines are live; choose one:";
    for (const auto& p : live) error += " " + p;
  }
  return std::nullopt;
}

Expected<ControlReply> Commands::send(const std::string& pipeline, ControlRequest request) {
  request.id = static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  return client_.command(pipeline, std::move(request), timeout_);
}

std::string Commands::run(const std::string& body) {
  json reply = {{"ok", false}};
  std::string error;
  const json j = json::parse(body, nullptr, false);
  const std::string named = j.is_object() ? text_field(j, "pipeline") : "";
  auto request = request_from_json(body, error);
  auto pipeline = request ? pipeline_for(named, error) : std::nullopt;
  if (!request || !pipeline) {
    reply["message"] = error;
    return reply.dump();
  }
  reply["pipeline"] = *pipeline;
  reply["kind"] = request->kind;
  auto answer = send(*pipeline, *request);
  if (!answer) {
    reply["message"] = answer.error();
    return reply.dump();
  }
  reply["ok"] = answer->ok;
  reply["message"] = answer->message;
  reply["value"] = answer->value;
  return reply.dump();
}

std::string Commands::parameters(const std::string& named) {
  std::string error;
  const auto pipeline = pipeline_for(named, error);
  if (!pipeline) return json{{"ok", false}, {"message", error}}.dump();
  ControlRequest list;
  list.kind = "list";
  auto listing = send(*pipeline, list);
  if (!listing) return json{{"ok", false}, {"message", listing.error()}}.dump();
  if (!listing->ok) return json{{"ok", false}, {"message", listing->message}}.dump();
  json parameters = json::array();
  for (const auto& p : parse_parameter_list(listing->value)) {
    json entry = {{"name", p.name}, {"min", p.min}, {"max", p.max}, {"integer", p.integer},
                  {"boolean", p.boolean}, {"unit", p.unit}, {"description", p.description}};
    ControlRequest get;
    get.kind = "get";
    std::string ignored;
    split_target(p.name, get, ignored);
    auto value = send(*pipeline, get);
    entry["value"] = value && value->ok ? value->value : "";
    parameters.push_back(std::move(entry));
  }
  return json{{"ok", true}, {"pipeline", *pipeline}, {"message", listing->message}, {"parameters", parameters}}.dump();
}

}  // namespace lode::cli::scope
