#include "vme_pentek.hpp"

#include <cmath>
#include <cstdio>

#include "lode/sdk/clock.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace {

using hal::hex;

/// One `adc:` or `dac:` list entry. Problems are reported on the entry's own keys.
hal::AnalogChannel parse_channel(Params& p, bool output) {
  hal::AnalogChannel c;
  c.name = p.text("name");
  c.bits = static_cast<int>(p.integer("bits", 16));
  const std::vector<double> span = p.numbers("span_v", std::vector<double>{-10.0, 10.0}, 2);
  if (span.size() == 2) {
    c.span_min_v = span[0];
    c.span_max_v = span[1];
  }
  const std::string coding = p.choice("coding", {"twos_complement", "offset_binary", "unipolar"}, "twos_complement");
  c.coding = coding == "offset_binary" ? hal::Coding::offset_binary
             : coding == "unipolar"    ? hal::Coding::unipolar
                                       : hal::Coding::twos_complement;
  c.gain = p.number("gain", 1.0);
  c.offset = p.number("offset", 0.0);
  c.unit = canonical_unit(p.text("unit", "V"));
  if (output) c.safe_value = p.number("safe_value", 0.0);
  if (const Status st = hal::validate(c); !st) {
    // validate() names the field in its message; report it on the entry.
    p.fail(st.message());
  }
  return c;
}

Elements elements_of(const std::vector<hal::AnalogChannel>& channels) {
  Elements out;
  for (const auto& c : channels) out.push_back({c.name, c.unit});
  return out;
}

}  // namespace

Status VmePentekBoard::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  device_ = params.text("device");
  const std::int64_t offset = params.integer("offset", 0);
  params.check(offset >= 0, "offset", "must be >= 0 (bytes into the device), got " + std::to_string(offset));
  offset_ = static_cast<std::uint64_t>(std::max<std::int64_t>(0, offset));
  external_trigger_ = params.choice("trigger", {"software", "external"}, "software") == "external";
  // The register map: a parse error names the map's file and line and is reported on the key,
  // so the pipeline does not load.
  register_map_ = params.file_path("register_map", "");
  layout_ = vme::Layout::default_layout();
  if (!register_map_.empty()) {
    auto layout = vme::load_layout(register_map_);
    if (layout) layout_ = *layout;
    else params.fail("register_map", "invalid register map:\n" + layout.error());
  }
  const double timeout_us = params.number("conversion_timeout_us", 100.0);
  params.check(timeout_us > 0.0 && timeout_us <= 1e6, "conversion_timeout_us",
               "must be within (0, 1e6] us, got " + std::to_string(timeout_us));
  conversion_timeout_ns_ = static_cast<std::int64_t>(timeout_us * 1e3);
  adc_.clear();
  dac_.clear();
  for (Params& item : params.items("adc")) adc_.push_back(parse_channel(item, false));
  if (params.has("dac"))
    for (Params& item : params.items("dac")) dac_.push_back(parse_channel(item, true));
  params.check(adc_.size() <= layout_.adc_data.count, "adc",
               "at most " + std::to_string(layout_.adc_data.count) + " channels (ADC_DATA of the register map)");
  params.check(dac_.size() <= layout_.dac_data.count, "dac",
               "at most " + std::to_string(layout_.dac_data.count) + " channels (DAC_DATA of the register map)");
  adc_conv_.clear();
  dac_conv_.clear();
  for (const auto& c : adc_) adc_conv_.emplace_back(c);
  for (const auto& c : dac_) dac_conv_.emplace_back(c);
  declare_ports(ctx, elements_of(dac_), elements_of(adc_));
  return {};
}

Status VmePentekBoard::activate() {
  const vme::Layout& l = layout_;
  auto window = hal::RegisterWindow::open(device_, offset_, l.window);
  if (!window) return Status::error(window.error());
  window_ = std::move(*window);
  // Every register this block touches, checked once here (the parser checked the map against
  // its own window already; this is the guard for the mapping itself); the RT path then does
  // only the access.
  for (const std::size_t reg : {l.board_id, l.control, l.status, l.channels, l.trigger, l.dac_load, l.reset_errors}) {
    if (auto st = window_.check(reg, 4); !st) return st;
  }
  for (std::size_t i = 0; i < adc_.size(); ++i)
    if (auto st = window_.check(l.adc_data.at(i), 4); !st) return st;
  for (std::size_t i = 0; i < dac_.size(); ++i)
    if (auto st = window_.check(l.dac_data.at(i), 4); !st) return st;
  const std::uint32_t id = window_.read32(l.board_id);
  if (id == vme::kNoAnswer)
    return Status::error(window_.describe() + ": no board answers (BOARD_ID reads 0xffffffff: bus error or no board)");
  if ((id & l.board_id_mask) != l.board_id_value)
    return Status::error(window_.describe() + ": BOARD_ID " + hex(id) + " is not a Pentek-like 6102 pair (expected " +
                         hex(l.board_id_value) + " under mask " + hex(l.board_id_mask) + ")");
  const std::uint32_t channels = window_.read32(l.channels);
  const std::size_t board_adc = l.adc_channels.get(channels), board_dac = l.dac_channels.get(channels);
  if (adc_.size() > board_adc || dac_.size() > board_dac)
    return Status::error(window_.describe() + ": the configuration uses " + std::to_string(adc_.size()) + " ADC and " +
                         std::to_string(dac_.size()) + " DAC channels; the board has " + std::to_string(board_adc) +
                         " and " + std::to_string(board_dac));
  window_.write32(l.control, l.enable | (external_trigger_ ? l.ext_trigger : 0u));
  window_.write32(l.reset_errors, 1);
  last_sequence_ = l.sequence.get(window_.read32(l.status));
  dac_clips_.store(0, std::memory_order_relaxed);
  drive_safe();  // outputs start at their safe values
  dac_load_pending_ = false;  // the board need not have latched them before the first cycle
  zero_inputs();
  return {};
}

StepStatus VmePentekBoard::board_fault(const char* reason, std::uint32_t status) noexcept {
  last_status_.store(status, std::memory_order_relaxed);  // describe() shows it
  return fault(reason);
}

StepStatus VmePentekBoard::step(const Tick& /*tick*/) noexcept {
  if (!window_.mapped()) return fault("register window not mapped (activate() failed)");
  const vme::Layout& l = layout_;
  if (const std::uint32_t status = window_.read32(l.status); status == vme::kNoAnswer)
    return board_fault("no answer from the board (STATUS reads all ones: VME bus error)", status);
  if (!external_trigger_) window_.write32(l.trigger, 1);
  const std::int64_t deadline = monotonic_ns() + conversion_timeout_ns_;
  std::uint32_t status = 0;
  for (;;) {
    status = window_.read32(l.status);
    if (status == vme::kNoAnswer) return board_fault("no answer from the board (STATUS reads all ones: VME bus error)", status);
    if ((status & l.done) != 0 && l.sequence.get(status) != last_sequence_) break;
    if (monotonic_ns() > deadline) {
      // TRIGGER first, then STATUS again: a board taking the trigger sets BUSY before it
      // clears TRIGGER, so the pair read in this order is consistent.
      const bool trigger_pending = !external_trigger_ && window_.read32(l.trigger) != 0;
      status = window_.read32(l.status);
      return board_fault((status & l.busy) != 0 ? "conversion did not complete within conversion_timeout_us (BUSY)"
                         : trigger_pending ? "the board did not take the trigger within conversion_timeout_us (not answering)"
                                           : "no new conversion within conversion_timeout_us",
                         status);
    }
  }
  std::atomic_thread_fence(std::memory_order_acquire);  // data after the STATUS that announced them
  // The board acts on DAC_LOAD (rung at the end of the last cycle) before a TRIGGER rung after
  // it: once this conversion is done, the last DAC values must have been latched.
  if (dac_load_pending_ && window_.read32(l.dac_load) != 0)
    return board_fault("the board did not latch the last DAC values (DAC_LOAD still set)", status);
  dac_load_pending_ = false;
  if ((status & l.error_mask()) != 0) {
    if (status & l.err_bus) return board_fault("board error bit: VME bus error", status);
    if (status & l.err_adc) return board_fault("board error bit: ADC fault", status);
    if (status & l.err_dac) return board_fault("board error bit: DAC fault", status);
    return board_fault("board error bit: trigger overrun", status);
  }
  last_sequence_ = l.sequence.get(status);
  last_status_.store(status, std::memory_order_relaxed);
  for (std::size_t i = 0; i < adc_.size(); ++i) {
    const std::uint32_t raw = window_.read32(l.adc_data.at(i));
    signals_[i] = adc_conv_[i].code_to_value(raw);
    counts_[i] = static_cast<double>(adc_conv_[i].code_index(raw));
  }
  return StepStatus::ok;
}

StepStatus VmePentekBoard::write(const Tick& /*tick*/) noexcept {
  if (!window_.mapped()) return fault("register window not mapped (activate() failed)");
  std::uint64_t clipped_now = 0;
  for (std::size_t i = 0; i < dac_.size(); ++i) {
    if (!std::isfinite(command_[i])) {
      drive_safe();
      return fault("non-finite command: DAC outputs driven to their safe values");
    }
    bool clipped = false;
    window_.write32(layout_.dac_data.at(i), dac_conv_[i].value_to_code(command_[i], clipped));
    clipped_now += clipped ? 1 : 0;
  }
  if (!dac_.empty()) {
    std::atomic_thread_fence(std::memory_order_release);  // data before the doorbell
    window_.write32(layout_.dac_load, 1);
    dac_load_pending_ = true;
  }
  if (clipped_now > 0) dac_clips_.fetch_add(clipped_now, std::memory_order_relaxed);
  return StepStatus::ok;
}

void VmePentekBoard::drive_safe() noexcept {
  if (!window_.mapped()) return;
  for (std::size_t i = 0; i < dac_.size(); ++i) window_.write32(layout_.dac_data.at(i), dac_conv_[i].safe_code());
  std::atomic_thread_fence(std::memory_order_release);
  if (!dac_.empty()) window_.write32(layout_.dac_load, 1);
}

void VmePentekBoard::deactivate() noexcept {
  drive_safe();
  window_ = hal::RegisterWindow();  // unmap; the board keeps driving the safe values
}

void VmePentekBoard::describe(Json& out) const {
  out["device"] = device_;
  out["offset"] = hex(offset_);
  out["register_map"] = register_map_.empty() ? std::string("built-in (pentek6102_dvme622.regmap)") : register_map_;
  out["trigger"] = external_trigger_ ? "external" : "software";
  out["conversion_timeout_us"] = static_cast<double>(conversion_timeout_ns_) * 1e-3;
  auto channels = [](const std::vector<hal::AnalogChannel>& list, const std::vector<hal::AnalogConversion>& conv,
                     bool output) {
    Json a = Json::array();
    for (std::size_t i = 0; i < list.size(); ++i) {
      Json c = Json::object();
      c["name"] = list[i].name;
      c["bits"] = static_cast<double>(list[i].bits);
      c["coding"] = hal::to_string(list[i].coding);
      c["lsb_v"] = conv[i].lsb_v();
      c["unit"] = list[i].unit;
      c["resolution"] = std::abs(list[i].gain) * conv[i].lsb_v();  // one code, in the channel's unit
      if (output) c["safe_value"] = list[i].safe_value;
      a.push(std::move(c));
    }
    return a;
  };
  out["adc"] = channels(adc_, adc_conv_, false);
  out["dac"] = channels(dac_, dac_conv_, true);
  out["dac_clips"] = static_cast<double>(dac_clips());
  out["last_status"] = hex(last_status());
}

namespace {

constexpr ParamDoc kParams[] = {
    {"device", "text", nullptr,
     "the register window: a UIO device (/dev/uioN), /dev/mem behind a VME bridge, or the emulator's file"},
    {"offset", "integer", "0", "byte offset of the board's window in `device` (need not be page aligned)"},
    {"register_map", "text", "built-in",
     "register-map file (README.md: format; pentek6102_dvme622.regmap is the built-in map), relative to the "
     "pipeline file's directory"},
    {"trigger", "text", "software", "software (this block rings TRIGGER each cycle) or external (the board's input)"},
    {"conversion_timeout_us", "number", "100", "longest wait for a conversion; longer is a fault [us]"},
    {"adc", "list<map>", nullptr,
     "ADC channels: {name, bits: 16, span_v: [-10, 10], coding: twos_complement|offset_binary|unipolar, "
     "gain: 1, offset: 0, unit: V}; value = gain * volts + offset"},
    {"dac", "list<map>", "none", "DAC channels, as adc plus safe_value (driven on any fault, stop or signal) [unit]"},
};

constexpr PortSpec kPorts[] = {
    {"command", PortDirection::in, "one element per dac channel, in its unit (written at the end of the cycle)", "with dac channels"},
    {"signals", PortDirection::out, "one element per adc channel, calibrated, in its unit (read at the start of the cycle)"},
    {"counts", PortDirection::out, "signed code index of each ADC sample [1]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::VmePentekBoard, "io.vme_pentek", lode::PluginKind::io, "0.1.0",
            "Pentek-like VME ADC/DAC board pair through a memory-mapped register window",
            lode::plugins::kParams, lode::plugins::kPorts)
