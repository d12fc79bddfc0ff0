// filter.external_gain: out = gain * input, element names and units passed through.
#include <lode/sdk/block.hpp>
#include <lode/sdk/plugin.hpp>

namespace {

class ExternalGain final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    gain_ = ctx.params().number("gain");
    ctx.declare_input(in_, "input", {});
    const lode::Elements* source = ctx.input_source("input");
    if (!source) return lode::Status::error("input must come from a non-io block");
    ctx.declare_output(out_, "out", *source);
    return ctx.params().ok() ? lode::Status::ok() : lode::Status::error("invalid parameters");
  }
  lode::StepStatus step(const lode::Tick&) noexcept override {
    for (std::size_t i = 0; i < out_.size(); ++i) out_[i] = gain_ * in_[i];
    return lode::StepStatus::ok;
  }
  void describe(lode::Json& out) const override { out["gain"] = gain_; }

 private:
  double gain_ = 1.0;
  lode::InputPort in_;
  lode::OutputPort out_;
};

const lode::ParamDoc kParams[] = {{"gain", "number", nullptr, "multiplier"}};
const lode::PortSpec kPorts[] = {{"input", lode::PortDirection::in, "any vector"}, {"out", lode::PortDirection::out, "gain * input"}};

}  // namespace

LODE_PLUGIN(ExternalGain, "filter.external_gain", lode::PluginKind::filter, "1.0.0",
            "Out-of-tree example: multiplies its input by a gain", kParams, kPorts)
