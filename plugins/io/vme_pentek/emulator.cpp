#include "emulator.hpp"

#include <chrono>

#include "register_map.hpp"

namespace lode::vme {

Expected<std::unique_ptr<PentekEmulator>> PentekEmulator::create(const std::string& path, std::uint64_t offset,
                                                                 std::size_t adc_channels, std::size_t dac_channels,
                                                                 Frontend frontend, std::uint32_t revision) {
  if (adc_channels > kMaxChannels || dac_channels > kMaxChannels)
    return Status::error("VME emulator: at most " + std::to_string(kMaxChannels) + " ADC and DAC channels");
  if (auto st = hal::RegisterWindow::create_file(path, static_cast<std::size_t>(offset) + kWindowLength); !st)
    return Status::error("VME emulator: " + st.message());
  auto window = hal::RegisterWindow::open(path, offset, kWindowLength);
  if (!window) return Status::error("VME emulator: " + window.error());
  std::unique_ptr<PentekEmulator> e(new PentekEmulator());
  e->window_ = std::move(*window);
  e->adc_channels_ = adc_channels;
  e->dac_channels_ = dac_channels;
  e->board_id_ = kBoardIdValue | (revision & 0xffu);
  e->frontend_ = std::move(frontend);
  e->dac_latched_.assign(dac_channels, 0);
  e->adc_codes_.assign(adc_channels, 0);
  e->dac_published_ = std::vector<std::atomic<std::uint32_t>>(dac_channels);
  auto& w = e->window_;
  for (std::size_t i = 0; i < kWindowLength; i += 4) w.write32(i, 0);
  w.write32(kBoardId, e->board_id_);
  w.write32(kChannels, static_cast<std::uint32_t>(adc_channels | (dac_channels << 8)));
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
  const auto fault = static_cast<Fault>(fault_.load());
  if (fault == Fault::no_answer) {
    // An absent board: the bridge returns all ones for every read.
    for (std::size_t i = 0; i < kWindowLength; i += 4) w.write32(i, kNoAnswer);
    return false;
  }
  if (fault == Fault::silent) return false;
  if (w.read32(kBoardId) != board_id_) w.write32(kBoardId, board_id_);  // recovered from no_answer
  bool acted = false;
  std::uint32_t status = w.read32(kStatus);
  if (status == kNoAnswer) status = sequence_ << kSequenceShift;
  if (w.read32(kResetErrors) != 0) {
    status &= ~kErrorMask;
    w.write32(kStatus, status);
    w.write32(kResetErrors, 0);
    acted = true;
  }
  if (w.read32(kDacLoad) != 0) {
    for (std::size_t i = 0; i < dac_channels_; ++i) {
      dac_latched_[i] = w.read32(dac_data(i));
      dac_published_[i].store(dac_latched_[i]);
    }
    w.write32(kDacLoad, 0);
    dac_loads_.fetch_add(1);
    acted = true;
  }
  if (w.read32(kTrigger) != 0) {
    if (status & kBusy) status |= kErrOverrun;
    // BUSY first, so the host never sees DONE with stale data.
    status = (status & ~kDone) | kBusy;
    w.write32(kStatus, status);
    w.write32(kTrigger, 0);
    if (fault == Fault::never_complete) return true;
    if (frontend_) frontend_(dac_latched_, adc_codes_);
    for (std::size_t i = 0; i < adc_channels_; ++i) w.write32(adc_data(i), adc_codes_[i]);
    ++sequence_;
    status = (status & kErrorMask) | kDone | (sequence_ << kSequenceShift);
    if (fault == Fault::error_bits) status |= fault_bits_.load();
    // Data before STATUS: a host that sees the new SEQUENCE reads the new data.
    std::atomic_thread_fence(std::memory_order_release);
    w.write32(kStatus, status);
    conversions_.fetch_add(1);
    acted = true;
  }
  return acted;
}

void PentekEmulator::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] {
    while (running_.load(std::memory_order_relaxed)) {
      if (!poll()) std::this_thread::sleep_for(std::chrono::microseconds(20));
    }
  });
}

void PentekEmulator::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

}  // namespace lode::vme
