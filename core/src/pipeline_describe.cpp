// lode describe: the resolved pipeline as JSON, with what every block reports of itself.
#include "lode/sdk/clock.hpp"
#include "lode/config_file.hpp"
#include "lode/pipeline.hpp"

#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstring>
#include <fstream>
#include <limits>
#include <deque>
#include <map>
#include <set>
#include <sstream>

#include "lode/telemetry.hpp"
#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

namespace {

Json elements_json(const Elements& e) {
  Json a = Json::array();
  for (const auto& el : e) {
    Json j = Json::object();
    j["name"] = el.name;
    j["unit"] = el.unit;
    a.push(std::move(j));
  }
  return a;
}


/// YAML node -> Json (for echoing resolved parameters in describe()).
Json to_json(const YAML::Node& n) {
  if (n.IsMap()) {
    Json j = Json::object();
    for (const auto& kv : n) j[kv.first.as<std::string>()] = to_json(kv.second);
    return j;
  }
  if (n.IsSequence()) {
    Json j = Json::array();
    for (const auto& e : n) j.push(to_json(e));
    return j;
  }
  if (n.IsScalar()) {
    const auto& s = n.Scalar();
    if (s == "true" || s == "false") return Json(s == "true");
    char* end = nullptr;
    const double d = std::strtod(s.c_str(), &end);
    if (end && *end == '\0' && !s.empty()) return Json(d);
    return Json(s);
  }
  return Json();
}

}  // namespace

Json Pipeline::describe() const {
  const Impl& im = *impl_;
  Json j = Json::object();
  j["pipeline"] = im.name;
  j["file"] = im.file;
  j["rate_hz"] = im.rate_hz;
  j["period_s"] = 1.0 / im.rate_hz;
  Json rt = Json::object();
  rt["priority"] = im.realtime.priority;
  rt["cpu"] = im.realtime.cpu;
  rt["lock_memory"] = im.realtime.lock_memory;
  rt["overrun_policy"] = im.realtime.overrun_policy == OverrunPolicy::stop       ? "stop"
                         : im.realtime.overrun_policy == OverrunPolicy::catch_up ? "catch_up"
                                                                                 : "skip";
  rt["max_overruns"] = im.realtime.max_overruns;
  rt["spin_us"] = im.realtime.spin_us;
  rt["clock"] = im.realtime.real_clock ? "real" : "sim";
  j["realtime"] = std::move(rt);
  if (impl_->telemetry.enabled) {
    const auto& t = impl_->telemetry;
    Json tj = Json::object();
    tj["domain"] = static_cast<std::int64_t>(t.domain);
    tj["transport"] = to_string(t.transport.kind);
    Json topics = Json::array();
    for (const auto& s : t.signals) {
      Json sj = Json::object();
      sj["topic"] = s.topic;
      sj["signal"] = s.signal.name();
      sj["rate_hz"] = s.rate_hz(impl_->rate_hz);
      sj["decimation"] = static_cast<std::uint64_t>(s.decimation);
      topics.push(std::move(sj));
    }
    if (t.state) {
      Json sj = Json::object();
      sj["topic"] = t.state->topic;
      sj["signal"] = t.state->pose.name();
      sj["rate_hz"] = impl_->rate_hz / t.state->decimation;
      sj["decimation"] = static_cast<std::uint64_t>(t.state->decimation);
      topics.push(std::move(sj));
    }
    tj["topics"] = std::move(topics);
    tj["timing_topic"] = pipeline_topic(impl_->name, "timing");
    tj["events_topic"] = pipeline_topic(impl_->name, "events");
    tj["commands"] = t.commands.enabled;
    if (t.commands.enabled) tj["command_topic"] = pipeline_topic(impl_->name, "command");
    tj["security"] = t.security.enabled();
    j["telemetry"] = std::move(tj);
  }
  Json order = Json::array();
  for (const auto& op : im.ops) order.push(op.label);
  j["cycle_order"] = std::move(order);
  Json models = Json::object();
  for (const auto& [name, spec] : im.models) {
    Json m = to_json(spec.node);
    models[name] = std::move(m);
  }
  j["models"] = std::move(models);
  Json blocks = Json::object();
  for (const auto& role : im.blocks) {
    if (!role->block && role->live.load() == role.get()) continue;
    // The instance now in the role (a hot swap or promotion may have changed it).
    const BlockEntry* b = role->live.load(std::memory_order_acquire);
    if (!b || !b->block) b = role.get();
    if (!b->block) continue;
    Json bj = Json::object();
    bj["plugin"] = b->plugin_name;
    bj["kind"] = to_string(b->plugin.descriptor->kind);
    bj["plugin_file"] = b->plugin.path;
    if (!role->shadow_of.empty()) {
      bj["shadow_of"] = role->shadow_of;
      bj["shadow_decimation"] = static_cast<std::uint64_t>(role->shadow_decimation);
    }
    if (b != role.get()) bj["swapped_in_from"] = b->name;
    Json params = to_json(b->node);
    Json clean = Json::object();
    for (const auto& [k, v] : params.members())
      if (std::find(kPipelineBlockKeys.begin(), kPipelineBlockKeys.end(), k) == kPipelineBlockKeys.end()) clean[k] = v;
    bj["parameters"] = std::move(clean);
    Json ins = Json::object();
    for (const auto& d : b->inputs) {
      Json ij = Json::object();
      std::string src;
      for (const auto& w : b->wiring)
        if (w.input == d.name) src = w.source;
      ij["from"] = src.empty() ? Json() : Json(src);
      ij["required"] = d.required;
      if (!src.empty()) {
        auto s = im.signal(src);
        if (s) ij["elements"] = elements_json(*s->elements);
      } else {
        ij["elements"] = elements_json(d.expected);
      }
      ins[d.name] = std::move(ij);
    }
    bj["inputs"] = std::move(ins);
    Json outs = Json::object();
    for (const auto& o : role->outputs) outs[o.name] = elements_json(o.elements);
    bj["outputs"] = std::move(outs);
    if (!b->layout.empty()) {
      Json st = Json::object();
      st["elements"] = elements_json(b->layout.elements);
      st["covariance"] = b->layout.covariance;
      bj["state"] = std::move(st);
    }
    Json derived = Json::object();
    b->block->describe(derived);
    bj["derived"] = std::move(derived);
    blocks[role->name] = std::move(bj);
  }
  j["blocks"] = std::move(blocks);
  // What the health monitor of each primary checks, with its derived NIS threshold.
  Json health = Json::object();
  for (const auto& f : im.families) {
    if (!f.health.enabled) continue;
    const HealthSpec& h = f.health;
    Json hj = Json::object();
    hj["non_finite"] = h.non_finite;
    hj["covariance_check_every"] = static_cast<std::uint64_t>(h.covariance_every);
    hj["nis_window"] = static_cast<std::uint64_t>(h.nis_window);
    hj["nis_threshold"] = h.nis_window > 0 ? Json(h.nis_threshold) : Json();
    hj["step_budget_us"] = static_cast<double>(h.step_budget_ns) * 1e-3;
    hj["budget_cycles"] = static_cast<std::uint64_t>(h.budget_cycles);
    hj["fallback"] = h.fallback_slot >= 0 ? Json(f.roles[static_cast<std::size_t>(h.fallback_slot + 1)]->name) : Json();
    health[f.primary->name] = std::move(hj);
  }
  j["health"] = std::move(health);
  return j;
}

}  // namespace lode
