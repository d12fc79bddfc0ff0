// A block whose configure() and port table disagree: it declares "out", which the table does
// not list, and leaves out "value", which the table lists as always present.
#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"

namespace {

class UndeclaredPort final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    ctx.declare_output(out_, "out", {{"x", "m"}});
    return lode::Status::ok();
  }
  lode::StepStatus step(const lode::Tick&) noexcept override { return lode::StepStatus::ok; }

 private:
  lode::OutputPort out_;
};

constexpr lode::ParamDoc kParams[] = {{"unused", "number", "0", "no parameter is read"}};
constexpr lode::PortSpec kPorts[] = {{"value", lode::PortDirection::out, "what the table promises"}};

}  // namespace

LODE_PLUGIN(UndeclaredPort, "test.undeclared_port", lode::PluginKind::source, "0.0.1",
            "Test plugin: configure() declares a port its table does not list", kParams, kPorts)
