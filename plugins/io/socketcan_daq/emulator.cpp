#include "emulator.hpp"

#include <linux/can/error.h>

#include <algorithm>

namespace lode::can_daq_emu {

namespace co = hal::canopen;

DaqNode::DaqNode(hal::CanSocket socket, int node, std::vector<co::PdoMapping> tpdo, std::vector<co::PdoMapping> rpdo,
                 Frontend frontend, std::chrono::milliseconds heartbeat_period)
    : socket_(std::move(socket)),
      node_(node),
      tpdo_(std::move(tpdo)),
      rpdo_(std::move(rpdo)),
      frontend_(std::move(frontend)),
      heartbeat_period_(heartbeat_period) {
  std::size_t n_out = 0, n_in = 0;
  for (const auto& m : rpdo_) n_out += m.entries.size();
  for (const auto& m : tpdo_) n_in += m.entries.size();
  outputs_.assign(n_out, 0);
  inputs_.assign(n_in, 0);
  outputs_published_ = std::vector<std::atomic<std::int64_t>>(n_out);
}

DaqNode::~DaqNode() { stop(); }

std::vector<std::int64_t> DaqNode::outputs() const {
  std::vector<std::int64_t> out;
  for (const auto& v : outputs_published_) out.push_back(v.load());
  return out;
}

void DaqNode::set_sync_watchdog(std::chrono::microseconds timeout, std::vector<std::int64_t> safe) {
  safe.resize(outputs_.size(), 0);
  sync_watchdog_ = timeout;
  safe_outputs_ = std::move(safe);
}

void DaqNode::send_heartbeat() {
  (void)socket_.send(co::heartbeat_frame(node_, static_cast<co::NmtState>(state_.load())));
}

bool DaqNode::poll() {
  const auto fault = static_cast<Fault>(fault_.load());
  if (fault == Fault::silent) return false;  // frozen: frames queue up unread, as on a hung node
  bool acted = false;
  hal::CanFrame f;
  const char* why = nullptr;
  while (socket_.receive(f, why) == hal::CanSocket::Receive::frame) {
    acted = true;
    if (f.error || f.extended || f.remote) continue;
    if (f.id == co::kNmt && f.length == 2 && (f.data[1] == node_ || f.data[1] == 0)) {
      switch (static_cast<co::NmtCommand>(f.data[0])) {
        case co::NmtCommand::start:
          state_.store(static_cast<int>(co::NmtState::operational));
          last_sync_ = std::chrono::steady_clock::now();  // the watchdog's time starts here
          break;
        case co::NmtCommand::stop: state_.store(static_cast<int>(co::NmtState::stopped)); break;
        default: state_.store(static_cast<int>(co::NmtState::pre_operational)); break;
      }
      if (fault != Fault::heartbeat_lost) send_heartbeat();  // a state change is announced at once
      continue;
    }
    if (f.id == co::kSync && f.length == 0) {
      syncs_.fetch_add(1);
      last_sync_ = std::chrono::steady_clock::now();
      if (state() != co::NmtState::operational) continue;
      if (frontend_) frontend_(outputs_, inputs_);
      std::size_t first = 0;
      for (const auto& m : tpdo_) {
        hal::CanFrame t;
        t.id = co::tpdo_cob(m.pdo, node_);
        co::pack_pdo(m, inputs_.data() + first, t);
        if (fault == Fault::malformed_pdo && t.length > 0) --t.length;
        if (socket_.send(t)) tpdos_sent_.fetch_add(1);
        first += m.entries.size();
      }
      continue;
    }
    std::size_t first = 0;
    for (const auto& m : rpdo_) {
      if (f.id == co::rpdo_cob(m.pdo, node_)) {
        if (co::unpack_pdo(m, f, outputs_.data() + first) == nullptr) {
          for (std::size_t k = 0; k < m.entries.size(); ++k) outputs_published_[first + k].store(outputs_[first + k]);
          rpdos_received_.fetch_add(1);
        }
        break;
      }
      first += m.entries.size();
    }
  }
  if (fault == Fault::bus_off && !(fault_sent_ & 1)) {
    hal::CanFrame e;
    e.error = true;
    e.id = CAN_ERR_BUSOFF;
    e.length = CAN_ERR_DLC;
    (void)socket_.send(e);
    fault_sent_ |= 1;
  }
  if (fault == Fault::emergency && !(fault_sent_ & 2)) {
    hal::CanFrame e;
    e.id = co::emcy_cob(node_);
    e.length = 8;
    e.data[0] = 0x10;  // 0x2310, little endian: output current too high
    e.data[1] = 0x23;
    e.data[2] = 0x02;  // error register: current
    (void)socket_.send(e);
    fault_sent_ |= 2;
  }
  const auto now = std::chrono::steady_clock::now();
  if (sync_watchdog_.count() > 0 && state() == co::NmtState::operational && now - last_sync_ > sync_watchdog_) {
    outputs_ = safe_outputs_;
    for (std::size_t k = 0; k < outputs_.size(); ++k) outputs_published_[k].store(outputs_[k]);
    state_.store(static_cast<int>(co::NmtState::pre_operational));
    watchdog_trips_.fetch_add(1);
    if (fault != Fault::heartbeat_lost) send_heartbeat();  // the master hears the state change
    acted = true;
  }
  if (now >= next_heartbeat_ && fault != Fault::heartbeat_lost) {
    send_heartbeat();
    next_heartbeat_ = now + heartbeat_period_;
    acted = true;
  }
  return acted;
}

void DaqNode::start() {
  poller_.start([this] { return poll(); }, [this] { wait_for_work(); });
}

void DaqNode::wait_for_work() {
  if (static_cast<Fault>(fault_.load()) == Fault::silent) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return;
  }
  // Sleep until a frame arrives or the next heartbeat (or watchdog check) is due, not on a
  // short fixed tick: in an emulated guest every needless wake-up costs the real ones time.
  auto until = next_heartbeat_;
  if (sync_watchdog_.count() > 0 && state() == hal::canopen::NmtState::operational)
    until = std::min(until, last_sync_ + sync_watchdog_);
  const auto wait = std::chrono::duration_cast<std::chrono::nanoseconds>(until - std::chrono::steady_clock::now());
  socket_.wait_readable(std::clamp<std::int64_t>(wait.count(), 50'000, 20'000'000));
}

void DaqNode::stop() { poller_.stop(); }

}  // namespace lode::can_daq_emu
