#include "emulator.hpp"

#include <chrono>


namespace lode::vme {

Expected<std::unique_ptr<PentekEmulator>> PentekEmulator::create(const std::string& path, std::uint64_t offset,
                                                                 const Layout& layout, std::size_t adc_channels,
                                                                 std::size_t dac_channels, Frontend frontend,
                                                                 std::uint32_t revision) {
  if (adc_channels > layout.adc_data.count || dac_channels > layout.dac_data.count)
    return Status::error("VME emulator: at most " + std::to_string(layout.adc_data.count) + " ADC and " +
                         std::to_string(layout.dac_data.count) + " DAC channels (ADC_DATA, DAC_DATA of the register map)");
  if (adc_channels > layout.adc_channels.max() || dac_channels > layout.dac_channels.max())
    return Status::error("VME emulator: " + std::to_string(adc_channels) + " ADC and " + std::to_string(dac_channels) +
                         " DAC channels do not fit the CHANNELS fields of the register map");
  if (auto st = hal::RegisterWindow::create_file(path, static_cast<std::size_t>(offset) + layout.window); !st)
    return Status::error("VME emulator: " + st.message());
  auto window = hal::RegisterWindow::open(path, offset, layout.window);
  if (!window) return Status::error("VME emulator: " + window.error());
  std::unique_ptr<PentekEmulator> e(new PentekEmulator());
  e->window_ = std::move(*window);
  e->layout_ = layout;
  e->adc_channels_ = adc_channels;
  e->dac_channels_ = dac_channels;
  // The revision goes into the bits the host does not compare.
  e->board_id_ = layout.board_id_value | (revision & ~layout.board_id_mask);
  e->frontend_ = std::move(frontend);
  e->dac_latched_.assign(dac_channels, 0);
  e->adc_codes_.assign(adc_channels, 0);
  e->dac_published_ = std::vector<std::atomic<std::uint32_t>>(dac_channels);
  auto& w = e->window_;
  for (std::size_t i = 0; i < layout.window; i += 4) w.write32(i, 0);
  w.write32(layout.board_id, e->board_id_);
  w.write32(layout.channels, layout.adc_channels.put(static_cast<std::uint32_t>(adc_channels)) |
                                 layout.dac_channels.put(static_cast<std::uint32_t>(dac_channels)));
  return e;
}

PentekEmulator::~PentekEmulator() { stop(); }

void PentekEmulator::set_fault(Fault fault, std::uint32_t error_bits) {
  fault_bits_.store(error_bits);
  fault_.store(static_cast<int>(fault));
}

std::vector<std::uint32_t> PentekEmulator::latched_dac() const {
  std::vector<std::uint32_t> out;
  for (const auto& v : dac_published_) out.push_back(v.load());
  return out;
}

bool PentekEmulator::poll() {
  auto& w = window_;
  const Layout& l = layout_;
  const auto fault = static_cast<Fault>(fault_.load());
  if (fault == Fault::no_answer) {
    // An absent board: the bridge returns all ones for every read.
    for (std::size_t i = 0; i < l.window; i += 4) w.write32(i, kNoAnswer);
    return false;
  }
  if (fault == Fault::silent) return false;
  if (w.read32(l.board_id) != board_id_) w.write32(l.board_id, board_id_);  // recovered from no_answer
  bool acted = false;
  std::uint32_t status = w.read32(l.status);
  if (status == kNoAnswer) status = l.sequence.put(sequence_);
  if (w.read32(l.reset_errors) != 0) {
    status &= ~l.error_mask();
    w.write32(l.status, status);
    w.write32(l.reset_errors, 0);
    acted = true;
  }
  if (w.read32(l.dac_load) != 0) {
    for (std::size_t i = 0; i < dac_channels_; ++i) {
      dac_latched_[i] = w.read32(l.dac_data.at(i));
      dac_published_[i].store(dac_latched_[i]);
    }
    w.write32(l.dac_load, 0);
    dac_loads_.fetch_add(1);
    acted = true;
  }
  if (w.read32(l.trigger) != 0) {
    if (status & l.busy) status |= l.err_overrun;
    // BUSY first, so the host never sees DONE with stale data.
    status = (status & ~l.done) | l.busy;
    w.write32(l.status, status);
    w.write32(l.trigger, 0);
    if (fault == Fault::never_complete) return true;
    if (frontend_) frontend_(dac_latched_, adc_codes_);
    for (std::size_t i = 0; i < adc_channels_; ++i) w.write32(l.adc_data.at(i), adc_codes_[i]);
    ++sequence_;
    status = (status & l.error_mask()) | l.done | l.sequence.put(sequence_);
    if (fault == Fault::error_bits) status |= fault_bits_.load();
    // Data before STATUS: a host that sees the new SEQUENCE reads the new data.
    std::atomic_thread_fence(std::memory_order_release);
    w.write32(l.status, status);
    conversions_.fetch_add(1);
    acted = true;
  }
  return acted;
}

void PentekEmulator::start() {
  poller_.start([this] { return poll(); }, [] { std::this_thread::sleep_for(std::chrono::microseconds(20)); });
}

void PentekEmulator::stop() { poller_.stop(); }

}  // namespace lode::vme
