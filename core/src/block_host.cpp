#include "lode/sdk/testing/block_host.hpp"

#include <yaml-cpp/yaml.h>

#include <stdexcept>

#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace lode {

// The host is a one-block pipeline loaded by the real loader: the block under test is
// named "dut" and each fed input comes from an output of the pseudo-block "feed".
struct BlockHost::Impl {
  std::string plugin;
  std::string params_yaml;
  double rate_hz;
  std::string models_yaml;
  std::vector<std::pair<std::string, Elements>> feeds;
  PluginRegistry registry;
  Diagnostics diagnostics;
  std::unique_ptr<Pipeline> pipeline;
  Block* dut = nullptr;
  Tick tick;
  bool stepped = false;
};

BlockHost::BlockHost(std::string plugin, std::string params_yaml, double rate_hz,
                           std::string models_yaml)
    : impl_(std::make_unique<Impl>()) {
  impl_->plugin = std::move(plugin);
  impl_->params_yaml = std::move(params_yaml);
  impl_->rate_hz = rate_hz;
  impl_->models_yaml = std::move(models_yaml);
  impl_->tick.dt_s = 1.0 / rate_hz;
}

BlockHost::~BlockHost() {
  if (impl_->pipeline) impl_->pipeline->deactivate();
}

void BlockHost::feed(const std::string& name, Elements elements) {
  impl_->feeds.emplace_back(name, std::move(elements));
}

Status BlockHost::configure() {
  YAML::Node root;
  root["pipeline"] = "block_host";
  root["rate_hz"] = impl_->rate_hz;
  YAML::Node params = impl_->params_yaml.empty() ? YAML::Node(YAML::NodeType::Map)
                                                 : YAML::Load(impl_->params_yaml);
  if (params.IsNull()) params = YAML::Node(YAML::NodeType::Map);
  params["plugin"] = impl_->plugin;
  for (const auto& [name, _] : impl_->feeds) params["inputs"][name] = "feed." + name;
  root["blocks"]["dut"] = params;
  if (!impl_->models_yaml.empty()) root["models"] = YAML::Load(impl_->models_yaml);
  YAML::Emitter out;
  out << root;
  impl_->pipeline = Pipeline::load_text(out.c_str(), "<block_host:" + impl_->plugin + ">",
                                        impl_->registry, impl_->diagnostics, impl_->feeds);
  if (!impl_->pipeline) return Status::error(impl_->diagnostics.format());
  impl_->dut = impl_->pipeline->block("dut");
  return {};
}

Status BlockHost::activate() {
  if (!impl_->pipeline) return Status::error("not configured");
  return impl_->pipeline->activate();
}

StepStatus BlockHost::step() {
  if (impl_->stepped) {
    ++impl_->tick.cycle;
    impl_->tick.time_ns = static_cast<std::int64_t>(
        static_cast<double>(impl_->tick.cycle) * 1e9 / impl_->rate_hz + 0.5);
  }
  impl_->stepped = true;
  return impl_->dut->step(impl_->tick);
}

StepStatus BlockHost::step_at(std::uint64_t cycle) {
  impl_->tick.cycle = cycle;
  impl_->tick.time_ns = static_cast<std::int64_t>(static_cast<double>(cycle) * 1e9 / impl_->rate_hz + 0.5);
  impl_->stepped = true;
  return impl_->dut->step(impl_->tick);
}

StepStatus BlockHost::write() { return board().write(impl_->tick); }

void BlockHost::deactivate() { impl_->pipeline->deactivate(); }

std::span<double> BlockHost::input(const std::string& name) {
  auto s = impl_->pipeline->signal("feed." + name);
  if (!s) throw std::out_of_range("no fed input '" + name + "'");
  return {const_cast<double*>(s->data), s->size()};
}

std::span<const double> BlockHost::output(const std::string& name) const {
  auto s = impl_->pipeline->signal("dut." + name);
  if (!s) throw std::out_of_range("no output '" + name + "'");
  return {s->data, s->size()};
}

const Elements& BlockHost::output_elements(const std::string& name) const {
  auto s = impl_->pipeline->signal("dut." + name);
  if (!s) throw std::out_of_range("no output '" + name + "'");
  return *s->elements;
}

Json BlockHost::describe() const {
  Json j = impl_->pipeline->describe();
  const Json* blocks = j.find("blocks");
  const Json* dut = blocks ? blocks->find("dut") : nullptr;
  const Json* derived = dut ? dut->find("derived") : nullptr;
  return derived ? *derived : Json();
}

std::string BlockHost::diagnostics() const { return impl_->diagnostics.format(); }
const Tick& BlockHost::tick() const { return impl_->tick; }
Block& BlockHost::block() { return *impl_->dut; }

namespace {
template <typename Interface>
Interface& interface_of(Block* dut, const std::string& plugin, const char* name) {
  auto* found = dynamic_cast<Interface*>(dut);
  if (!found) throw std::logic_error(plugin + " does not implement lode::" + name);
  return *found;
}
}  // namespace

Tunables& BlockHost::tunables() { return interface_of<Tunables>(impl_->dut, impl_->plugin, "Tunables"); }
EstimatorState& BlockHost::estimator() {
  return interface_of<EstimatorState>(impl_->dut, impl_->plugin, "EstimatorState");
}
Board& BlockHost::board() { return interface_of<Board>(impl_->dut, impl_->plugin, "Board"); }

}  // namespace lode
