#include "socketcan_daq.hpp"

#include <algorithm>
#include <cmath>

#include "lode/sdk/clock.hpp"
#include "lode/sdk/plugin.hpp"
#include "lode/sdk/units.hpp"

namespace lode::plugins {

namespace co = hal::canopen;

namespace can_daq {

std::int64_t count_of(const co::PdoEntry& entry, const Channel& channel, double value, bool& clipped) noexcept {
  const std::int64_t lo = entry.is_signed ? -(std::int64_t{1} << (entry.bits - 1)) : 0;
  const std::int64_t hi =
      entry.is_signed ? (std::int64_t{1} << (entry.bits - 1)) - 1 : (std::int64_t{1} << entry.bits) - 1;
  if (!std::isfinite(value)) {
    clipped = true;
    value = channel.safe_value;
  }
  const double c = std::floor((value - channel.offset) / channel.scale + 0.5);
  if (!(c >= static_cast<double>(lo))) {
    clipped = true;
    return lo;
  }
  if (c > static_cast<double>(hi)) {
    clipped = true;
    return hi;
  }
  return static_cast<std::int64_t>(c);
}

}  // namespace can_daq

namespace {

std::vector<can_daq::Pdo> parse_pdos(Params& params, const char* key, bool output) {
  std::vector<can_daq::Pdo> out;
  for (Params& p : params.items(key)) {
    can_daq::Pdo pdo;
    pdo.mapping.pdo = static_cast<int>(p.integer("pdo", 1));
    for (Params& e : p.items("entries")) {
      co::PdoEntry entry;
      can_daq::Channel ch;
      entry.name = ch.name = e.text("name");
      entry.bits = static_cast<int>(e.integer("bits", 16));
      entry.is_signed = e.flag("signed", true);
      ch.scale = e.number("scale", 1.0);
      e.check(std::isfinite(ch.scale) && ch.scale != 0.0, "scale", "must be finite and non-zero (unit per count)");
      ch.offset = e.number("offset", 0.0);
      ch.unit = canonical_unit(e.text("unit", "V"));
      if (output) ch.safe_value = e.number("safe_value", 0.0);
      pdo.mapping.entries.push_back(entry);
      pdo.channels.push_back(ch);
    }
    if (const Status st = co::validate(pdo.mapping); !st) {
      p.fail(st.message());
    } else if (output) {
      for (std::size_t i = 0; i < pdo.channels.size(); ++i) {
        bool clipped = false;
        (void)can_daq::count_of(pdo.mapping.entries[i], pdo.channels[i], pdo.channels[i].safe_value, clipped);
        if (clipped)
          p.fail("entry '" + pdo.channels[i].name + "': safe_value is outside what its " +
                 std::to_string(pdo.mapping.entries[i].bits) + "-bit object carries");
      }
    }
    for (const auto& other : out)
      if (other.mapping.pdo == pdo.mapping.pdo)
        p.fail(std::string(key) + " " + std::to_string(pdo.mapping.pdo) + " is configured twice");
    out.push_back(std::move(pdo));
  }
  return out;
}

Elements elements_of(const std::vector<can_daq::Pdo>& pdos) {
  Elements out;
  for (const auto& p : pdos)
    for (const auto& c : p.channels) out.push_back({c.name, c.unit});
  return out;
}

}  // namespace

Status SocketCanDaq::configure(ConfigureContext& ctx) {
  Params& params = ctx.params();
  interface_ = params.text("interface");
  node_ = static_cast<int>(params.integer("node_id"));
  params.check(node_ >= 1 && node_ <= 127, "node_id", "a CANopen node id is 1 ... 127, got " + std::to_string(node_));
  const double hb_ms = params.number("heartbeat_timeout_ms", 100.0);
  params.check(hb_ms > 0.0 && hb_ms <= 60000.0, "heartbeat_timeout_ms", "must be within (0, 60000] ms");
  heartbeat_timeout_ns_ = static_cast<std::int64_t>(hb_ms * 1e6);
  const double pdo_us = params.number("pdo_timeout_us", 1000.0);
  params.check(pdo_us > 0.0 && pdo_us <= 1e6, "pdo_timeout_us", "must be within (0, 1e6] us");
  pdo_timeout_ns_ = static_cast<std::int64_t>(pdo_us * 1e3);
  tpdo_ = parse_pdos(params, "tpdo", false);
  rpdo_ = params.has("rpdo") ? parse_pdos(params, "rpdo", true) : std::vector<can_daq::Pdo>{};
  output_count_ = 0;
  for (const auto& p : rpdo_) output_count_ += p.channels.size();
  tpdo_seen_.assign(tpdo_.size(), 0);
  raw_.assign(8, 0);
  declare_ports(ctx, elements_of(rpdo_), elements_of(tpdo_));
  return {};
}

Status SocketCanDaq::activate() {
  std::vector<hal::CanFilter> filters;
  for (const auto& p : tpdo_) filters.push_back({co::tpdo_cob(p.mapping.pdo, node_), 0x7ff});
  filters.push_back({co::heartbeat_cob(node_), 0x7ff});
  filters.push_back({co::emcy_cob(node_), 0x7ff});
  auto socket = hal::CanSocket::open(interface_, filters);
  if (!socket) return Status::error(socket.error());
  socket_ = std::move(*socket);
  received_.store(0);
  complete_.store(0);
  emcy_code_.store(0);
  sync_to_tpdo_.reset();
  // Outputs to their safe values first, then start the node and wait for it to say so.
  send_rpdos(true);
  if (!socket_.send(co::nmt_frame(co::NmtCommand::start, node_)))
    return Status::error("CAN interface '" + interface_ + "': cannot send NMT start (is the interface up?)");
  const std::int64_t deadline = monotonic_ns() + heartbeat_timeout_ns_;
  const char* last_state = "no heartbeat at all";
  for (;;) {
    hal::CanFrame f;
    const char* why = nullptr;
    const auto r = socket_.receive(f, why);
    if (r == hal::CanSocket::Receive::frame) {
      co::NmtState state{};
      if (f.id == co::heartbeat_cob(node_) && co::decode_heartbeat(f, state)) {
        if (state == co::NmtState::operational) break;
        last_state = co::to_string(state);
      }
      continue;
    }
    if (r == hal::CanSocket::Receive::failed) return Status::error("CAN interface '" + interface_ + "': " + why);
    const std::int64_t now = monotonic_ns();
    if (now >= deadline)
      return Status::error("CAN node " + std::to_string(node_) + " on " + interface_ +
                           " did not report operational within heartbeat_timeout_ms of NMT start (" + last_state + ")");
    socket_.wait_readable(deadline - now);
  }
  last_heartbeat_ns_ = monotonic_ns();
  zero_inputs();
  return {};
}

const char* SocketCanDaq::supervise(const hal::CanFrame& f, std::int64_t now_ns) noexcept {
  if (f.error) {
    const hal::CanErrorSummary e = hal::summarize_error(f);
    if (e.bus_off || e.error_passive || e.no_ack || e.tx_timeout || e.rx_overflow) return e.worst;
    return nullptr;  // warnings, lost arbitration, restarts: not faults
  }
  if (f.extended || f.remote) return nullptr;
  if (f.id == co::heartbeat_cob(node_)) {
    co::NmtState state{};
    if (!co::decode_heartbeat(f, state)) return "malformed heartbeat from the node";
    if (state != co::NmtState::operational) return "the node left the operational state (heartbeat)";
    last_heartbeat_ns_ = now_ns;
    return nullptr;
  }
  if (f.id == co::emcy_cob(node_)) {
    co::Emergency e;
    if (!co::decode_emergency(f, e)) return "malformed EMCY from the node";
    if (e.error_code != 0) {
      emcy_code_.store(e.error_code, std::memory_order_relaxed);
      return "EMCY from the node (error code in describe())";
    }
  }
  return nullptr;
}

StepStatus SocketCanDaq::step(const Tick& /*tick*/) noexcept {
  if (!socket_.is_open()) return fault("CAN socket not open (activate() failed)");
  hal::CanFrame f;
  const char* why = nullptr;
  std::int64_t now = monotonic_ns();
  // Whatever arrived since the last cycle: heartbeats, EMCY, error frames, late TPDOs (ignored).
  for (;;) {
    const auto r = socket_.receive(f, why);
    if (r == hal::CanSocket::Receive::none) break;
    if (r == hal::CanSocket::Receive::failed) return fault(why);
    if (r == hal::CanSocket::Receive::malformed) return fault("malformed CAN frame received");
    received_.fetch_add(1, std::memory_order_relaxed);
    if (const char* reason = supervise(f, now)) return fault(reason);
  }
  if (now - last_heartbeat_ns_ > heartbeat_timeout_ns_) return fault("heartbeat lost: none within heartbeat_timeout_ms");
  const std::int64_t sync_sent_ns = realtime_ns();  // the receive timestamps' clock
  if (!socket_.send(co::sync_frame())) return fault("CAN send refused (bus down or queue full)");
  std::int64_t last_tpdo_ns = 0;
  for (auto& s : tpdo_seen_) s = 0;
  std::size_t remaining = tpdo_.size();
  const std::int64_t deadline = now + pdo_timeout_ns_;
  while (remaining > 0) {
    const auto r = socket_.receive(f, why);
    if (r == hal::CanSocket::Receive::failed) return fault(why);
    if (r == hal::CanSocket::Receive::malformed) return fault("malformed CAN frame received");
    if (r == hal::CanSocket::Receive::frame) {
      received_.fetch_add(1, std::memory_order_relaxed);
      bool was_tpdo = false;
      std::size_t first = 0;
      for (std::size_t i = 0; i < tpdo_.size(); ++i) {
        const auto& pdo = tpdo_[i];
        if (!f.extended && !f.error && f.id == co::tpdo_cob(pdo.mapping.pdo, node_)) {
          was_tpdo = true;
          if (const char* bad = co::unpack_pdo(pdo.mapping, f, raw_.data())) return fault(bad);
          for (std::size_t k = 0; k < pdo.channels.size(); ++k) {
            counts_[first + k] = static_cast<double>(raw_[k]);
            signals_[first + k] = can_daq::value_of(pdo.channels[k], raw_[k]);
          }
          if (!tpdo_seen_[i]) {
            tpdo_seen_[i] = 1;
            --remaining;
            last_tpdo_ns = std::max(last_tpdo_ns, f.timestamp_ns);
          }
          break;
        }
        first += pdo.channels.size();
      }
      if (!was_tpdo)
        if (const char* reason = supervise(f, monotonic_ns())) return fault(reason);
      continue;
    }
    now = monotonic_ns();
    if (now >= deadline) return fault("TPDO missing: not received within pdo_timeout_us of SYNC");
    socket_.wait_readable(deadline - now);
  }
  complete_.fetch_add(1, std::memory_order_relaxed);
  if (last_tpdo_ns > 0) sync_to_tpdo_.record(last_tpdo_ns - sync_sent_ns);
  return StepStatus::ok;
}

void SocketCanDaq::send_rpdos(bool safe) noexcept {
  std::size_t first = 0;
  for (const auto& pdo : rpdo_) {
    for (std::size_t k = 0; k < pdo.channels.size(); ++k) {
      bool clipped = false;
      const double v = safe ? pdo.channels[k].safe_value : command_[first + k];
      raw_[k] = can_daq::count_of(pdo.mapping.entries[k], pdo.channels[k], v, clipped);
    }
    hal::CanFrame f;
    f.id = co::rpdo_cob(pdo.mapping.pdo, node_);
    co::pack_pdo(pdo.mapping, raw_.data(), f);
    (void)socket_.send(f);
    first += pdo.channels.size();
  }
}

StepStatus SocketCanDaq::write(const Tick& /*tick*/) noexcept {
  if (!socket_.is_open()) return fault("CAN socket not open (activate() failed)");
  for (std::size_t i = 0; i < output_count_; ++i) {
    if (!std::isfinite(command_[i])) {
      drive_safe();
      return fault("non-finite command: outputs driven to their safe values");
    }
  }
  std::size_t first = 0;
  for (const auto& pdo : rpdo_) {
    for (std::size_t k = 0; k < pdo.channels.size(); ++k) {
      bool clipped = false;
      raw_[k] = can_daq::count_of(pdo.mapping.entries[k], pdo.channels[k], command_[first + k], clipped);
    }
    hal::CanFrame f;
    f.id = co::rpdo_cob(pdo.mapping.pdo, node_);
    co::pack_pdo(pdo.mapping, raw_.data(), f);
    if (!socket_.send(f)) return fault("CAN send refused (bus down or queue full)");
    first += pdo.channels.size();
  }
  return StepStatus::ok;
}

void SocketCanDaq::drive_safe() noexcept {
  if (socket_.is_open()) send_rpdos(true);
}

void SocketCanDaq::deactivate() noexcept {
  if (!socket_.is_open()) return;
  send_rpdos(true);
  (void)socket_.send(co::nmt_frame(co::NmtCommand::pre_operational, node_));
  socket_ = hal::CanSocket();
}

void SocketCanDaq::describe(Json& out) const {
  out["interface"] = interface_;
  out["node_id"] = static_cast<double>(node_);
  out["heartbeat_timeout_ms"] = static_cast<double>(heartbeat_timeout_ns_) * 1e-6;
  out["pdo_timeout_us"] = static_cast<double>(pdo_timeout_ns_) * 1e-3;
  auto pdos = [&](const std::vector<can_daq::Pdo>& list, bool transmit) {
    Json a = Json::array();
    for (const auto& p : list) {
      Json j = Json::object();
      j["pdo"] = static_cast<double>(p.mapping.pdo);
      j["cob_id"] = static_cast<double>(transmit ? co::tpdo_cob(p.mapping.pdo, node_) : co::rpdo_cob(p.mapping.pdo, node_));
      j["bytes"] = static_cast<double>(p.mapping.bytes());
      Json entries = Json::array();
      for (std::size_t k = 0; k < p.channels.size(); ++k) {
        Json e = Json::object();
        e["name"] = p.channels[k].name;
        e["bits"] = static_cast<double>(p.mapping.entries[k].bits);
        e["signed"] = p.mapping.entries[k].is_signed;
        e["scale"] = p.channels[k].scale;
        e["offset"] = p.channels[k].offset;
        e["unit"] = p.channels[k].unit;
        if (!transmit) e["safe_value"] = p.channels[k].safe_value;
        entries.push(std::move(e));
      }
      j["entries"] = std::move(entries);
      a.push(std::move(j));
    }
    return a;
  };
  out["tpdo"] = pdos(tpdo_, true);
  out["rpdo"] = pdos(rpdo_, false);
  out["frames_received"] = static_cast<double>(frames_received());
  out["complete_cycles"] = static_cast<double>(complete_cycles());
  out["last_emergency_code"] = static_cast<double>(last_emergency_code());
  // Kernel receive time of the cycle's last TPDO minus the SYNC's send time: the module's and
  // the bus's latency, without this thread's wake-up and scheduling delays.
  out["sync_to_tpdo_us"] = sync_to_tpdo_.summary_us();
}

namespace {

constexpr ParamDoc kParams[] = {
    {"interface", "text", nullptr, "SocketCAN interface (vcan0, can0), or fd:N (a socket pair end, tests)"},
    {"node_id", "integer", nullptr, "CANopen node id of the DAQ module, 1 ... 127"},
    {"heartbeat_timeout_ms", "number", "100", "no heartbeat for this long is a fault; also the wait after NMT start [ms]"},
    {"pdo_timeout_us", "number", "1000", "every TPDO must arrive this soon after SYNC [us]"},
    {"tpdo", "list<map>", nullptr,
     "what the module sends after SYNC: {pdo: 1..4, entries: [{name, bits: 8|16|32, signed: true, scale: "
     "<unit per count>, offset: 0, unit: V}]}, packed little endian in order"},
    {"rpdo", "list<map>", "none", "what this block sends (the module's outputs): as tpdo, entries add safe_value [unit]"},
};

constexpr PortSpec kPorts[] = {
    {"command", PortDirection::in, "every rpdo entry, in its unit (written at the end of the cycle)", "with rpdo entries"},
    {"signals", PortDirection::out, "every tpdo entry, scaled, in its unit"},
    {"counts", PortDirection::out, "the raw integers of the TPDO entries [1]"},
};

}  // namespace

}  // namespace lode::plugins

LODE_PLUGIN(lode::plugins::SocketCanDaq, "io.socketcan_daq", lode::PluginKind::io, "0.1.0",
            "CANopen-style analog DAQ module over SocketCAN: NMT, SYNC, PDOs, heartbeat and EMCY supervision",
            lode::plugins::kParams, lode::plugins::kPorts)
