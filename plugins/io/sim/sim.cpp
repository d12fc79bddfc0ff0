#include "sim.hpp"

#include "lode/sdk/rt_log.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <set>

#include "board_ports.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/text.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace {

std::string name_list(const Elements& elements) {
  std::string out;
  for (const auto& e : elements) out += (out.empty() ? "" : ", ") + e.name;
  return out;
}

/// Widest converter whose counts stay exact in a double with a wide margin.
constexpr std::int64_t kMaxAdcBits = 32;
constexpr std::int64_t kMaxSubsteps = 100000;

}  // namespace

Status SimBoard::configure(ConfigureContext& ctx) {
  block_name_ = ctx.block_name();
  Params& params = ctx.params();

  // --- plant ---------------------------------------------------------------------------
  plant_name_ = params.text("plant");
  if (!plant_name_.empty()) plant_ = ctx.plant_model("plant");  // nullptr: the context said why
  const Elements no_elements;
  const Elements& plant_inputs = plant_ ? plant_->inputs() : no_elements;
  const Elements& plant_outputs = plant_ ? plant_->outputs() : no_elements;
  input_count_ = plant_inputs.size();

  // --- sensors -------------------------------------------------------------------------
  const Status sensors_status = configure_sensors(ctx, params);

  // --- acquisition chain ---------------------------------------------------------------
  noise_std_v_ = params.number("noise_std_v", 1e-3);
  params.check(noise_std_v_ >= 0.0, "noise_std_v", "must be >= 0 V, got " + number_text(noise_std_v_));
  adc_bits_ = params.integer("adc_bits", 16);
  if (!(adc_bits_ == 0 || (adc_bits_ >= 2 && adc_bits_ <= kMaxAdcBits))) {
    params.fail("adc_bits", "must be 0 (no quantization) or within 2 ... 32, got " +
                                std::to_string(adc_bits_));
    adc_bits_ = 0;
  }
  adc_range_v_ = params.number("adc_range_v", 10.0);
  params.check(adc_range_v_ > 0.0, "adc_range_v",
               "must be > 0 V (the converter spans +-adc_range_v), got " + number_text(adc_range_v_));
  if (adc_bits_ > 0 && adc_range_v_ > 0.0) {
    converter_ = sim::ConverterScale::of(static_cast<int>(adc_bits_), adc_range_v_);
  }
  mains_amplitude_v_ = params.number("mains_amplitude_v", 0.0);
  params.check(mains_amplitude_v_ >= 0.0, "mains_amplitude_v",
               "must be >= 0 V, got " + number_text(mains_amplitude_v_));
  mains_frequency_hz_ = params.number("mains_frequency_hz", 60.0);
  params.check(mains_frequency_hz_ >= 0.0, "mains_frequency_hz",
               "must be >= 0 Hz, got " + number_text(mains_frequency_hz_));
  mains_phase_rad_ = params.number("mains_phase_rad", 0.0);
  // Sizes are only enforced when known: a failed model must not cause follow-on errors.
  channel_offset_v_ = params.numbers(
      "channel_offset_v", std::vector<double>(channel_count_, 0.0),
      sensors_status ? std::optional<std::size_t>(channel_count_) : std::nullopt);
  channel_offset_v_.resize(channel_count_, 0.0);
  seed_ = static_cast<std::uint64_t>(params.integer("seed", 1));

  // --- commands ------------------------------------------------------------------------
  safe_command_ = params.numbers("safe_command", std::vector<double>(input_count_, 0.0),
                                 plant_ ? std::optional<std::size_t>(input_count_) : std::nullopt);
  safe_command_.resize(input_count_, 0.0);
  if (params.has("command_limit")) {
    command_limit_ = params.numbers("command_limit",
                                    plant_ ? std::optional<std::size_t>(input_count_) : std::nullopt);
    command_limit_.resize(input_count_, 0.0);
    for (std::size_t i = 0; i < command_limit_.size(); ++i) {
      if (!(command_limit_[i] > 0.0)) {
        params.fail("command_limit", "every limit must be > 0, got " +
                                         number_text(command_limit_[i]) + " for " +
                                         plant_inputs[i].name);
      }
    }
    for (std::size_t i = 0; i < safe_command_.size() && i < command_limit_.size(); ++i) {
      if (std::abs(safe_command_[i]) > command_limit_[i]) {
        params.fail("safe_command", "safe value " + number_text(safe_command_[i]) + " for " +
                                        plant_inputs[i].name + " exceeds command_limit " +
                                        number_text(command_limit_[i]));
      }
    }
  } else {
    params.numbers("command_limit", std::vector<double>{});  // record the optional key as read
  }
  substeps_ = params.integer("substeps", 1);
  if (substeps_ < 1 || substeps_ > kMaxSubsteps) {
    params.fail("substeps", "must be within 1 ... 100000, got " + std::to_string(substeps_));
    substeps_ = 1;
  }

  // --- fault injection --------------------------------------------------------------------
  nan_window_ = FaultWindow{};
  if (std::optional<Params> inject = params.optional_child("inject_nan")) {
    parse_injection_window(*inject, sensors_status.is_ok(), nan_window_);
  }
  stuck_window_ = FaultWindow{};
  if (std::optional<Params> stuck = params.optional_child("inject_stuck")) {
    stuck_holds_last_ = !stuck->has("value_v");
    const double value_v = stuck_holds_last_ ? 0.0 : stuck->number("value_v");
    stuck->check(std::isfinite(value_v), "value_v", "must be a finite voltage, got " + number_text(value_v));
    // Through the converter like any reading (quantized, clipped to the code range), so
    // `signals` and `counts` agree.
    stuck_count_ = value_v;
    stuck_signal_v_ = value_v;
    if (converter_.quantizes() && std::isfinite(value_v)) {
      bool clipped = false;
      stuck_count_ = converter_.code(value_v, clipped);
      stuck_signal_v_ = stuck_count_ * converter_.lsb_v;
    }
    parse_injection_window(*stuck, sensors_status.is_ok(), stuck_window_);
  }

  // --- ports and buffers ------------------------------------------------------------------
  // Declared even when something above failed, so that the pipeline reports the real
  // problem and not a missing port on top of it.
  // A plant without actuators (e.g. a stage moved by its own trajectory) has no DAC side.
  if (!plant_ || !plant_inputs.empty()) ctx.declare_input(command_, "command", plant_inputs, true);
  if (plant_) {
    ctx.declare_output(truth_, "truth", plant_outputs);
    ctx.declare_output(plant_state_, "plant_state", plant_->state_elements());
  }
  if (sensors_status) {
    Elements channels;
    for (const auto& slot : sensors_) {
      const Elements& c = slot.model->channels();
      channels.insert(channels.end(), c.begin(), c.end());
    }
    ctx.declare_output(signals_, "signals", channels);
    ctx.declare_output(counts_, "counts", boards::counts_of(channels));
  }
  truth_buffer_.assign(plant_outputs.size(), 0.0);
  clean_signals_.assign(channel_count_, 0.0);
  volts_.assign(channel_count_, 0.0);
  held_command_.assign(input_count_, 0.0);
  plain_write_ = command_limit_.empty() && substeps_ == 1;

  if (!params.ok()) return Status::error("invalid parameters");
  if (!plant_) {
    return Status::error("plant model '" + plant_name_ + "' is not available (see above)");
  }
  return sensors_status;
}

void SimBoard::parse_injection_window(Params& window, bool sensors_ok, FaultWindow& out) {
  out.channel = -1;
  const std::string name = window.text("channel");
  const double start_s = window.number("start_s");
  const double duration_s = window.number("duration_s");
  window.check(std::isfinite(start_s) && start_s >= 0.0, "start_s",
               "must be >= 0 s (scheduled time since start), got " + number_text(start_s));
  window.check(std::isfinite(duration_s) && duration_s > 0.0, "duration_s",
               "must be > 0 s, got " + number_text(duration_s));
  if (sensors_ok) {
    std::size_t index = 0;
    bool found = false;
    std::string names;
    for (const auto& slot : sensors_) {
      for (const auto& e : slot.model->channels()) {
        names += (names.empty() ? "" : ", ") + e.name;
        if (!found && e.name == name) {
          found = true;
          out.channel = static_cast<std::int64_t>(index);
        }
        if (!found) ++index;
      }
    }
    if (!found) window.fail("channel", "no channel '" + name + "' on this board (channels: " + names + ")");
  }
  if (window.ok()) {
    out.start_ns = std::llround(start_s * 1e9);
    out.end_ns = out.start_ns + std::llround(duration_s * 1e9);
  } else {
    out.channel = -1;
  }
}

Status SimBoard::configure_sensors(ConfigureContext& ctx, Params& params) {
  const std::vector<std::string> names = params.texts("sensors", {});
  std::vector<ModelPtr<MeasurementModel>> models = ctx.measurement_models("sensors");
  if (!params.has("sensors")) return Status::error("no sensors");  // reported by the context
  if (names.empty()) {
    params.fail("sensors", "list at least one measurement model from `models:`");
    return Status::error("no sensors");
  }
  // A model that could not be made was reported and left out of the list.
  if (models.size() != names.size()) {
    return Status::error("a sensor model is not available (see above)");
  }
  if (!plant_) return Status::error("no plant to check the sensors against");
  std::size_t largest_state = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    SensorSlot slot;
    slot.name = names[i];
    slot.model = std::move(models[i]);
    sensors_.push_back(std::move(slot));
  }

  // Every state element a sensor needs must be a plant output, by name and unit.
  const Elements& outputs = plant_->outputs();
  std::set<std::string> channel_names;
  bool ok = true;
  channel_count_ = 0;
  for (auto& slot : sensors_) {
    for (const auto& need : slot.model->state_elements()) {
      const auto found = std::find_if(outputs.begin(), outputs.end(),
                                      [&](const Element& e) { return e.name == need.name; });
      if (found == outputs.end()) {
        params.fail("sensors", "sensor model '" + slot.name + "' needs state element '" +
                                   need.name + "' [" + need.unit + "], which plant '" +
                                   plant_name_ + "' does not output (its outputs: " +
                                   name_list(outputs) + ")");
        ok = false;
        continue;
      }
      if (!units_compatible(found->unit, need.unit)) {
        params.fail("sensors", "sensor model '" + slot.name + "' needs '" + need.name + "' in [" +
                                   need.unit + "], plant '" + plant_name_ + "' outputs it in [" +
                                   found->unit + "]");
        ok = false;
      }
      slot.truth_index.push_back(static_cast<std::size_t>(found - outputs.begin()));
    }
    slot.reads_truth_prefix = true;
    for (std::size_t j = 0; j < slot.truth_index.size(); ++j)
      slot.reads_truth_prefix = slot.reads_truth_prefix && slot.truth_index[j] == j;
    largest_state = std::max(largest_state, slot.model->state_elements().size());
    slot.first_channel = channel_count_;
    slot.channel_count = slot.model->channels().size();
    channel_count_ += slot.channel_count;
    for (const auto& channel : slot.model->channels()) {
      if (!channel_names.insert(channel.name).second) {
        params.fail("sensors", "channel '" + channel.name + "' of sensor model '" + slot.name +
                                   "' is also produced by an earlier sensor; channel names must "
                                   "be unique on the board");
        ok = false;
      }
    }
  }
  if (channel_count_ == 0) {
    params.fail("sensors", "the sensor models produce no channels");
    ok = false;
  }
  sensor_state_.assign(largest_state, 0.0);
  return ok ? Status::ok() : Status::error("sensor models do not fit the plant");
}

Status SimBoard::activate() {
  plant_->reset();
  noise_.seed(seed_);
  safe_.store(false, std::memory_order_relaxed);
  for (auto& u : held_command_) u = 0.0;
  inject_live_channel_.store(-1, std::memory_order_relaxed);
  // Outputs are valid before the first cycle: the noise-free sample of the initial state.
  if (sample(0, false) != StepStatus::ok) return Status::error(fault_reason());
  saturations_.store(0, std::memory_order_relaxed);
  command_clamps_.store(0, std::memory_order_relaxed);
  return Status::ok();
}

StepStatus SimBoard::step(const Tick& tick) noexcept { return sample(tick.time_ns, true); }

Json SimBoard::FaultWindow::describe() const {
  Json window = Json::object();
  window["channel_index"] = static_cast<double>(channel);
  window["start_s"] = static_cast<double>(start_ns) * 1e-9;
  window["end_s"] = static_cast<double>(end_ns) * 1e-9;
  window["window"] = "start_s <= scheduled time < end_s";
  return window;
}

StepStatus SimBoard::sample(std::int64_t time_ns, bool in_cycle) noexcept {
  const bool with_noise = in_cycle;
  plant_->output(truth_buffer_.data());
  for (std::size_t i = 0; i < truth_buffer_.size(); ++i) {
    if (!std::isfinite(truth_buffer_[i])) return fault("non-finite plant output");
    truth_[i] = truth_buffer_[i];
  }
  plant_->state(plant_state_.data());

  for (const auto& slot : sensors_) {
    // A model whose state is the plant's first outputs in order reads them where they are.
    const double* state = truth_buffer_.data();
    if (!slot.reads_truth_prefix) {
      for (std::size_t j = 0; j < slot.truth_index.size(); ++j)
        sensor_state_[j] = truth_buffer_[slot.truth_index[j]];
      state = sensor_state_.data();
    }
    slot.model->evaluate(state, clean_signals_.data() + slot.first_channel);
  }

  // Mains pick-up is common to every channel (the same 60 Hz field couples into all wires, as
  // in Kawato 2005). Reduce the cycle count before taking the sine: exact phase on long runs.
  double mains_v = 0.0;
  if (with_noise && mains_amplitude_v_ > 0.0) {
    const double cycles = mains_frequency_hz_ * static_cast<double>(time_ns) * 1e-9;
    const double fraction = cycles - std::floor(cycles);
    mains_v = mains_amplitude_v_ * std::sin(2.0 * std::numbers::pi * fraction + mains_phase_rad_);
  }

  // Which channel (if any) each fault injection hits on this cycle, decided once.
  Injections injections;
  if (in_cycle) {
    injections.stuck = stuck_window_.active(time_ns);
    injections.live_nan = inject_live_channel_.load(std::memory_order_relaxed);
    injections.window_nan = nan_window_.active(time_ns);
    // A frozen converter repeats its last conversion: the reading of the previous cycle.
    if (injections.stuck >= 0 && static_cast<std::size_t>(injections.stuck) < channel_count_) {
      injections.previous_count = counts_[static_cast<std::size_t>(injections.stuck)];
      injections.previous_signal = signals_[static_cast<std::size_t>(injections.stuck)];
    }
  }

  // The volts of every channel first, the noise drawn in channel order (a draw per channel, up
  // to a non-finite one), then the converter: a loop without calls keeps its values in registers.
  const std::size_t channels = channel_count_;
  const bool noisy = with_noise && noise_std_v_ > 0.0;
  for (std::size_t c = 0; c < channels; ++c) {
    double v = clean_signals_[c] + channel_offset_v_[c] + mains_v;
    if (noisy) v += noise_std_v_ * noise_();
    volts_[c] = v;
    if (!std::isfinite(v)) {
      // The channels before it keep their readings of this cycle, injections included.
      convert(c);
      inject(c, injections);
      return fault("non-finite simulated signal");
    }
  }
  const std::uint64_t saturated = convert(channels);
  if (injections.any()) inject(channels, injections);
  if (saturated > 0) {
    saturations_.fetch_add(saturated, std::memory_order_relaxed);
    if (!was_saturated_)
      lode::rt_log(lode::LogLevel::warn, block_name_.c_str(),
                   "ADC saturated on {} channel(s) (range +-{} V)", static_cast<double>(saturated),
                   adc_range_v_);
  }
  was_saturated_ = saturated > 0;
  return StepStatus::ok;
}

std::uint64_t SimBoard::convert(std::size_t channels) noexcept {
  std::uint64_t saturated = 0;
  const double* volts = volts_.data();
  double* counts = counts_.data();
  double* signals = signals_.data();
  if (converter_.quantizes()) {
    const sim::ConverterScale converter = converter_;
    for (std::size_t c = 0; c < channels; ++c) {
      bool clipped = false;
      const double code = converter.code(volts[c], clipped);
      saturated += clipped ? 1 : 0;
      counts[c] = code;
      signals[c] = code * converter.lsb_v;
    }
  } else {
    // No converter modelled: counts carry the volts unchanged (an LSB of 1 V).
    for (std::size_t c = 0; c < channels; ++c) {
      counts[c] = volts[c];
      signals[c] = volts[c];
    }
  }
  return saturated;
}

void SimBoard::inject(std::size_t channels, const Injections& injections) noexcept {
  // After the noise draws, so the generator's sequence does not depend on the injection; a
  // NaN injection wins over a stuck value on the same channel.
  const auto hit = [channels](std::int64_t c) { return c >= 0 && static_cast<std::size_t>(c) < channels; };
  if (hit(injections.stuck)) {
    const auto c = static_cast<std::size_t>(injections.stuck);
    counts_[c] = stuck_holds_last_ ? injections.previous_count : stuck_count_;
    signals_[c] = stuck_holds_last_ ? injections.previous_signal : stuck_signal_v_;
  }
  for (const std::int64_t nan : {injections.live_nan, injections.window_nan}) {
    if (!hit(nan)) continue;
    counts_[static_cast<std::size_t>(nan)] = std::numeric_limits<double>::quiet_NaN();
    signals_[static_cast<std::size_t>(nan)] = std::numeric_limits<double>::quiet_NaN();
  }
}

StepStatus SimBoard::write(const Tick& tick) noexcept {
  if (safe_.load(std::memory_order_relaxed)) {
    advance_plant(tick.dt_s, safe_command_.data());
    return StepStatus::ok;
  }
  const std::size_t inputs = input_count_;
  const double* command = command_.data();
  bool finite = true;
  for (std::size_t i = 0; i < inputs; ++i) finite = finite && std::isfinite(command[i]);
  if (!finite) {
    // The DAC goes to its safe values; the plant keeps moving under them.
    drive_safe();
    advance_plant(tick.dt_s, safe_command_.data());
    return fault("non-finite command");
  }
  // Nothing to clamp, one step (dt / 1 is dt): the plant takes the command port as it is.
  if (plain_write_) {
    plant_->advance(tick.dt_s, command);
    return StepStatus::ok;
  }
  std::uint64_t clamped = 0;
  for (std::size_t i = 0; i < input_count_; ++i) {
    double u = command_[i];
    if (!command_limit_.empty() && std::abs(u) > command_limit_[i]) {
      u = std::clamp(u, -command_limit_[i], command_limit_[i]);
      ++clamped;
    }
    held_command_[i] = u;
  }
  if (clamped > 0) command_clamps_.fetch_add(clamped, std::memory_order_relaxed);
  advance_plant(tick.dt_s, held_command_.data());
  return StepStatus::ok;
}

void SimBoard::advance_plant(double dt_s, const double* u) noexcept {
  const double sub_dt_s = dt_s / static_cast<double>(substeps_);
  for (std::int64_t s = 0; s < substeps_; ++s) plant_->advance(sub_dt_s, u);
}

void SimBoard::drive_safe() noexcept { safe_.store(true, std::memory_order_relaxed); }

std::vector<Tunable> SimBoard::tunables() const {
  return {{"inject_nan_channel", "1", -1.0, static_cast<double>(channel_count_) - 1.0, true,
           "index of a channel whose signals and counts are NaN on every cycle from the next one "
           "(fault injection); -1 = off"}};
}

double SimBoard::tunable_value(std::size_t index) const noexcept {
  return index == 0 ? static_cast<double>(inject_live_channel_.load(std::memory_order_relaxed)) : 0.0;
}

bool SimBoard::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index != 0) {
    why = "no such parameter";
    return false;
  }
  if (!(value >= -1.0 && value <= static_cast<double>(channel_count_) - 1.0) || value != std::floor(value)) {
    why = "inject_nan_channel must be an integer channel index, or -1 for off";
    return false;
  }
  inject_live_channel_.store(static_cast<std::int64_t>(value), std::memory_order_relaxed);
  return true;
}

void SimBoard::describe(Json& out) const {
  out["plant"] = plant_name_;
  Json plant = Json::object();
  if (plant_) plant_->describe(plant);
  out["plant_model"] = std::move(plant);
  Json sensors = Json::array();
  for (const auto& slot : sensors_) {
    Json s = Json::object();
    s["name"] = slot.name;
    s["first_channel"] = static_cast<int>(slot.first_channel);
    s["channels"] = static_cast<int>(slot.channel_count);
    Json model = Json::object();
    slot.model->describe(model);
    s["model"] = std::move(model);
    sensors.push(std::move(s));
  }
  out["sensors"] = std::move(sensors);
  out["channels"] = static_cast<int>(channel_count_);

  out["adc_bits"] = static_cast<double>(adc_bits_);
  out["adc_range_v"] = adc_range_v_;
  const double quantization_std_v = converter_.lsb_v / std::sqrt(12.0);
  const double mains_rms_v = mains_amplitude_v_ / std::numbers::sqrt2;
  out["lsb_v"] = converter_.lsb_v;
  out["count_min"] = converter_.count_min;
  out["count_max"] = converter_.count_max;
  out["quantization_noise_std_v"] = quantization_std_v;
  out["white_noise_std_v"] = noise_std_v_;
  out["mains_rms_v"] = mains_rms_v;
  out["mains_frequency_hz"] = mains_frequency_hz_;
  // Independent contributions add in power (mains counted as its rms).
  out["total_noise_std_v"] = std::sqrt(noise_std_v_ * noise_std_v_ +
                                       quantization_std_v * quantization_std_v +
                                       mains_rms_v * mains_rms_v);
  out["channel_offset_v"] = channel_offset_v_;
  out["seed"] = static_cast<double>(seed_);
  out["substeps"] = static_cast<double>(substeps_);
  out["safe_command"] = safe_command_;
  if (!command_limit_.empty()) out["command_limit"] = command_limit_;
  out["adc_saturations"] = static_cast<double>(saturation_count());
  out["command_clamps"] = static_cast<double>(command_clamp_count());
  out["safe"] = safe();
  if (nan_window_.channel >= 0) out["inject_nan"] = nan_window_.describe();
  out["inject_nan_channel"] = static_cast<double>(inject_live_channel_.load(std::memory_order_relaxed));
  if (stuck_window_.channel >= 0) {
    Json stuck = stuck_window_.describe();
    if (stuck_holds_last_) {
      stuck["reads"] = "its last reading before the window (frozen converter)";
    } else {
      stuck["value_v"] = stuck_signal_v_;
      stuck["count"] = stuck_count_;
    }
    out["inject_stuck"] = std::move(stuck);
  }
}

namespace {

constexpr ParamDoc kParams[] = {
    {"plant", "text", nullptr, "name of a plant model in `models:` (e.g. plant.planar_stage)"},
    {"sensors", "text or list<text>", nullptr,
     "measurement-model names in `models:`; channels are concatenated in this order; their "
     "state elements must be plant outputs"},
    {"noise_std_v", "number", "1e-3", "white Gaussian noise std per channel [V] (thesis: 1 mV)"},
    {"adc_bits", "integer", "16", "converter resolution; 0 = no quantization or clipping"},
    {"adc_range_v", "number", "10", "converter input range +-adc_range_v [V]"},
    {"mains_amplitude_v", "number", "0", "mains interference amplitude on every channel [V]"},
    {"mains_frequency_hz", "number", "60", "mains interference frequency [Hz]"},
    {"mains_phase_rad", "number", "0", "mains interference phase at t = 0 [rad]"},
    {"channel_offset_v", "list<number>", "0 per channel", "offset added per channel [V]"},
    {"seed", "integer", "1", "noise generator seed (mt19937_64); same seed, same signals"},
    {"safe_command", "list<number>", "0 per plant input",
     "command held after a fault or drive_safe() [plant input units]"},
    {"command_limit", "list<number>", "none", "per plant input |u| clamp [plant input units]"},
    {"substeps", "integer", "1", "plant integration steps per cycle"},
    {"inject_nan", "map", "none",
     "fault injection: {channel: <channel name>, start_s: <s, >= 0>, duration_s: <s, > 0>} makes that "
     "channel's signals and counts NaN on cycles whose scheduled time is in [start_s, start_s + duration_s); "
     "tunable inject_nan_channel (index, -1 = off) does it live"},
    {"inject_stuck", "map", "none",
     "fault injection: {channel: <channel name>, start_s: <s, >= 0>, duration_s: <s, > 0>, value_v: <V, optional>} "
     "makes that channel read a constant on cycles whose scheduled time is in [start_s, start_s + duration_s): "
     "value_v through the converter (a disconnected or railed sensor), or without it the reading of the "
     "last cycle before the window (a frozen converter)"},
};

constexpr PortSpec kPorts[] = {
    {"command", PortDirection::in, "DAC command, exactly the plant's inputs (e.g. fx N, fy N, tz N*m)", "when the plant has inputs"},
    {"signals", PortDirection::out, "ADC channels [V] after offset, mains, noise and quantization"},
    {"counts", PortDirection::out, "raw signed ADC counts per channel [1]"},
    {"truth", PortDirection::out, "plant outputs (true configuration), e.g. x m, y m, theta_z rad"},
    {"plant_state", PortDirection::out, "full plant state, e.g. x, y, theta_z, vx, vy, omega_z"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::SimBoard, "io.sim", lode::PluginKind::io, "0.1.0",
            "Simulated ADC/DAC board: plant + measurement models + noise, mains, offsets, ADC",
            lode::plugins::kParams, lode::plugins::kPorts)
