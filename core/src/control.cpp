#include "lode/control.hpp"
#include "lode/sdk/rt_log.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <thread>

namespace lode {

namespace {
std::string format_number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  // Shortest form that round-trips, for people: try fewer digits first.
  for (int digits = 6; digits < 17; ++digits) {
    char shorter[64];
    std::snprintf(shorter, sizeof shorter, "%.*g", digits, v);
    if (std::strtod(shorter, nullptr) == v) return shorter;
  }
  return buf;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string range_text(const Tunable& t) {
  if (t.unit == "bool") return "true|false";
  std::string r = "[" + format_number(t.min) + ", " + format_number(t.max) + "]";
  if (t.integer) r += " integer";
  if (!t.unit.empty() && t.unit != "1") r += " " + t.unit;
  return r;
}

ControlReply fail(const ControlRequest& r, std::string message) {
  ControlReply reply;
  reply.id = r.id;
  reply.ok = false;
  reply.message = std::move(message);
  return reply;
}
}  // namespace

ControlService::ControlService(Pipeline& pipeline, EventLog& events) : pipeline_(pipeline), events_(events) {
  for (const auto& name : pipeline_.block_names()) {
    Entry e;
    e.block = name;
    e.slot = pipeline_.block_slot(name);
    e.instance = pipeline_.block(name);
    e.interface = dynamic_cast<Tunables*>(e.instance);
    if (e.interface) e.tunables = e.interface->tunables();
    entries_.push_back(std::move(e));
  }
}

void ControlService::refresh() {
  // A hot swap, promotion or health fallback may have put another instance into a role:
  // its runtime parameters are those of the instance now running.
  for (auto& e : entries_) {
    Block* now = pipeline_.block(e.block);
    if (now != e.instance) {
      e.instance = now;
      e.interface = dynamic_cast<Tunables*>(now);
      e.tunables = e.interface ? e.interface->tunables() : std::vector<Tunable>{};
    }
  }
}

const ControlService::Entry* ControlService::find(const std::string& block) const {
  for (const auto& e : entries_)
    if (e.block == block) return &e;
  return nullptr;
}

void ControlService::before_cycle(const Tick& tick) noexcept {
  if (state_.load(std::memory_order_acquire) != kPosted) return;
  int expected = kPosted;
  if (!state_.compare_exchange_strong(expected, kBusy, std::memory_order_acq_rel)) return;
  box_cycle_ = tick.cycle;
  box_time_ns_ = tick.time_ns;
  if (box_slot_ && *box_slot_ != box_block_) {
    // The health monitor swapped the block between validation and this boundary.
    box_ok_ = false;
    box_why_ = "the block was swapped (health fallback) while the command was in flight; retry";
    box_previous_ = box_now_ = 0.0;
    state_.store(kDone, std::memory_order_release);
    return;
  }
  box_previous_ = box_tunables_->tunable_value(box_index_);
  box_why_ = "";
  box_ok_ = box_write_ ? box_tunables_->set_tunable(box_index_, box_value_, box_why_) : true;
  box_now_ = box_tunables_->tunable_value(box_index_);
  state_.store(kDone, std::memory_order_release);
}

bool ControlService::parse_value(const std::string& text, const Tunable& t, double& value, std::string& error) {
  const std::string v = lower(text);
  if (t.unit == "bool" || (t.integer && t.min == 0 && t.max == 1)) {
    if (v == "true" || v == "on" || v == "yes" || v == "1") {
      value = 1;
      return true;
    }
    if (v == "false" || v == "off" || v == "no" || v == "0") {
      value = 0;
      return true;
    }
    error = "'" + text + "' is not a switch value (true/false, on/off, 1/0)";
    return false;
  }
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  if (text.empty() || end == text.c_str() || *end != '\0') {
    error = "'" + text + "' is not a number";
    return false;
  }
  if (!std::isfinite(value)) {
    error = "'" + text + "' is not finite";
    return false;
  }
  if (value < t.min || value > t.max) {
    error = "value " + format_number(value) + " is outside " + range_text(t);
    return false;
  }
  if (t.integer && value != std::round(value)) {
    error = "value " + format_number(value) + " must be an integer";
    return false;
  }
  return true;
}

ControlReply ControlService::exchange(const ControlRequest& r, const Entry& e, std::size_t index, bool write,
                                      double value, std::chrono::milliseconds timeout) {
  box_block_ = e.instance;
  box_tunables_ = e.interface;
  box_slot_ = e.slot;
  box_index_ = index;
  box_write_ = write;
  box_value_ = value;
  const std::string what = e.block + "." + e.tunables[index].name;
  if (!running_.load(std::memory_order_acquire)) {
    // No RT thread: this thread owns the blocks. Apply directly, same code path.
    state_.store(kPosted, std::memory_order_release);
    Tick idle;
    before_cycle(idle);
    box_cycle_ = 0;
    box_time_ns_ = 0;
  } else {
    state_.store(kPosted, std::memory_order_release);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (state_.load(std::memory_order_acquire) != kDone) {
      if (std::chrono::steady_clock::now() > deadline) {
        int expected = kPosted;
        if (state_.compare_exchange_strong(expected, kIdle, std::memory_order_acq_rel))
          return fail(r, what + ": not applied: the pipeline did not reach a cycle boundary within " +
                             std::to_string(timeout.count()) + " ms");
        // The RT thread holds it: it finishes within one call of set_tunable().
      }
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  }
  const bool ok = box_ok_;
  const double previous = box_previous_;
  const double now = box_now_;
  const char* why = box_why_;
  const std::uint64_t cycle = box_cycle_;
  const std::int64_t time_ns = box_time_ns_;
  state_.store(kIdle, std::memory_order_release);

  ControlReply reply;
  reply.id = r.id;
  reply.ok = ok;
  reply.value = format_number(now);
  if (!write) {
    reply.message = what + " = " + reply.value + (e.tunables[index].unit.empty() ? "" : " " + e.tunables[index].unit);
  } else if (ok) {
    reply.message = what + ": " + format_number(previous) + " -> " + format_number(now) + " at cycle " +
                    std::to_string(cycle);
    events_.post(time_ns, cycle, "parameter",
                 reply.message + (r.client.empty() ? "" : " (by " + r.client + ")"));
  } else {
    reply.message = what + ": refused by the block: " + std::string(why) + "; unchanged at " + format_number(now);
    events_.post_limited(time_ns, cycle, "command_failed", reply.message + (r.client.empty() ? "" : " (by " + r.client + ")"));
  }
  return reply;
}

ControlService::~ControlService() { join_workers(); }

void ControlService::handle_async(const ControlRequest& request, std::function<void(ControlReply)> answer,
                                  std::chrono::milliseconds timeout) {
  const auto answered = [this, timeout](const ControlRequest& r) {
    try {
      return handle(r, timeout);
    } catch (const std::exception& ex) {
      ControlReply reply;
      reply.id = r.id;
      reply.message = r.kind + ": internal error: " + ex.what();
      return reply;
    }
  };
  if (!is_swap(request)) {
    answer(answered(request));
    return;
  }
  std::lock_guard lock(workers_mutex_);
  for (std::size_t w = workers_.size(); w-- > 0;) {
    if (!workers_[w].done->load(std::memory_order_acquire)) continue;
    workers_[w].thread.join();
    workers_.erase(workers_.begin() + static_cast<std::ptrdiff_t>(w));
  }
  auto done = std::make_shared<std::atomic<bool>>(false);
  workers_.push_back({std::thread([answered, request, answer = std::move(answer), done] {
                        answer(answered(request));
                        done->store(true, std::memory_order_release);
                      }),
                      done});
}

void ControlService::join_workers() {
  std::vector<Worker> workers;
  {
    std::lock_guard lock(workers_mutex_);
    workers.swap(workers_);
  }
  for (auto& w : workers) w.thread.join();
}

ControlReply ControlService::handle(const ControlRequest& r, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (is_swap(r)) {
    if (!swap_handler_) return fail(r, r.kind + ": this pipeline runner has no hot-swap service");
    // The handler lets go of the lock while a newcomer runs as a shadow (which may last
    // minutes), so other commands are served meanwhile; it holds it again to finish.
    auto reply = swap_handler_(r, lock);
    if (!lock.owns_lock()) lock.lock();
    refresh();
    return reply;
  }
  refresh();
  if (r.kind == "record_start" || r.kind == "record_stop") {
    if (record_handler_) return record_handler_(r);
    return fail(r, r.kind + ": this pipeline runner has no recorder");
  }
  if (r.kind == "status") {
    ControlReply reply;
    reply.id = r.id;
    reply.ok = true;
    reply.message = "pipeline '" + pipeline_.name() + "' at " + format_number(pipeline_.rate_hz()) + " Hz, " +
                    (running_.load() ? "running" : "not running");
    reply.value = format_number(pipeline_.rate_hz());  // for clients: `lode swap --shadow-cycles` times its wait by it
    return reply;
  }
  if (r.kind == "list") {
    ControlReply reply;
    reply.id = r.id;
    reply.ok = true;
    std::size_t count = 0;
    for (const auto& e : entries_) {
      if (!r.block.empty() && e.block != r.block) continue;
      for (const auto& t : e.tunables) {
        reply.value += e.block + "." + t.name + " " + range_text(t) + "  " + t.description + "\n";
        ++count;
      }
    }
    if (!r.block.empty() && !find(r.block)) return fail(r, "list: no block '" + r.block + "'");
    reply.message = std::to_string(count) + " runtime parameter" + (count == 1 ? "" : "s");
    return reply;
  }
  if (r.kind != "set" && r.kind != "get")
    return fail(r, "unknown command kind '" + r.kind + "' (set, get, list, swap, promote, record_start, record_stop, status)");

  const Entry* e = find(r.block);
  if (!e) {
    std::string names;
    for (const auto& x : entries_) names += (names.empty() ? "" : ", ") + x.block;
    return fail(r, r.kind + ": no block '" + r.block + "' in pipeline '" + pipeline_.name() + "' (blocks: " + names + ")");
  }
  std::size_t index = e->tunables.size();
  for (std::size_t i = 0; i < e->tunables.size(); ++i)
    if (e->tunables[i].name == r.name) index = i;
  if (index == e->tunables.size()) {
    std::string names;
    for (const auto& t : e->tunables) names += (names.empty() ? "" : ", ") + t.name;
    return fail(r, r.kind + ": block '" + r.block + "' has no runtime parameter '" + r.name + "'" +
                       (names.empty() ? " (it has none)" : " (it has: " + names + ")"));
  }
  if (r.kind == "get") return exchange(r, *e, index, false, 0.0, timeout);
  double value = 0;
  std::string error;
  if (!parse_value(r.value, e->tunables[index], value, error)) {
    auto reply = fail(r, "set " + r.block + "." + r.name + ": " + error + "; unchanged");
    std::int64_t time_ns = 0;
    std::uint64_t cycle = 0;
    rt_log_clock(time_ns, cycle);  // refused before it reached the RT thread: the cycle running now
    events_.post_limited(time_ns, cycle, "command_failed", reply.message + (r.client.empty() ? "" : " (by " + r.client + ")"));
    return reply;
  }
  return exchange(r, *e, index, true, value, timeout);
}

}  // namespace lode
