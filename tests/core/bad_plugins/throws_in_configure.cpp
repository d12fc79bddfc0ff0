// A block whose configure() throws: the loader and the hot swap must refuse it and keep going.
#include <stdexcept>

#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"

namespace {
class ThrowsInConfigure final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& /*ctx*/) override {
    throw std::runtime_error("simulated bug in configure()");
  }
  lode::StepStatus step(const lode::Tick& /*tick*/) noexcept override { return lode::StepStatus::ok; }
};
constexpr lode::ParamDoc kParams[] = {{"anything", "number", "0", "never read"}};
constexpr lode::PortSpec kPorts[] = {{"pose", lode::PortDirection::out, "never declared"}};
}  // namespace

LODE_PLUGIN(ThrowsInConfigure, "test.throws_in_configure", lode::PluginKind::block, "0.0.1",
            "Test plugin: configure() throws", kParams, kPorts)
