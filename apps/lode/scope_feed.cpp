#include "scope_feed.hpp"

#include <algorithm>
#include <bit>
#include <optional>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "plot_html.hpp"  // base64

namespace lode::cli::scope {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

// ---------------------------------------------------------------------------------------------
// PageQueue

void PageQueue::push(std::shared_ptr<const std::string> message) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    if (messages_.size() >= capacity_) {
      messages_.pop_front();
      ++dropped_;
    }
    messages_.push_back(std::move(message));
  }
  ready_.notify_one();
}

std::vector<std::shared_ptr<const std::string>> PageQueue::take(std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, wait, [&] { return closed_ || !messages_.empty(); });
  std::vector<std::shared_ptr<const std::string>> out;
  if (closed_) return out;
  out.assign(std::make_move_iterator(messages_.begin()), std::make_move_iterator(messages_.end()));
  messages_.clear();
  return out;
}

void PageQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    messages_.clear();
  }
  ready_.notify_all();
}

bool PageQueue::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

std::uint64_t PageQueue::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

// ---------------------------------------------------------------------------------------------
// Helpers

namespace {

std::shared_ptr<const std::string> sse(const std::string& event, const std::string& data) {
  return std::make_shared<const std::string>("event: " + event + "\ndata: " + data + "\n\n");
}

json signal_json(const dds::SignalMeta& m) {
  return {{"topic", m.topic}, {"pipeline", m.pipeline}, {"block", m.block}, {"port", m.port},
          {"kind", m.kind},   {"names", m.names},       {"units", m.units}, {"rate_hz", m.rate_hz}};
}

json timing_row_json(const dds::TimingSample::Row& r) {
  return {{"name", r.name}, {"p50_us", r.p50_us}, {"p90_us", r.p90_us}, {"p99_us", r.p99_us},
          {"p999_us", r.p999_us}, {"max_us", r.max_us}, {"mean_us", r.mean_us}, {"count", r.count}};
}

json timing_json(const dds::TimingSample& t) {
  json blocks = json::array();
  for (const auto& b : t.blocks) blocks.push_back(timing_row_json(b));
  return {{"pipeline", t.pipeline},
          {"cycle", t.cycle},
          {"executed", t.executed},
          {"overruns", t.overruns},
          {"missed_periods", t.missed_periods},
          {"telemetry_dropped", t.telemetry_dropped},
          {"rate_hz", t.rate_hz},
          {"wake_latency", timing_row_json(t.wake_latency)},
          {"cycle_time", timing_row_json(t.cycle_time)},
          {"blocks", blocks}};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Feed

/// One watched signal topic. Rows of `width` doubles: cycle, stamp [s], then the values.
struct Feed::Topic {
  dds::SignalMeta meta;
  std::size_t width = 2;
  std::mutex mutex;  ///< the listener and the batching thread only
  std::vector<double> pending;
  std::uint64_t received = 0, dropped = 0;
  std::unique_ptr<dds::Subscription> subscription;
};

Feed::Feed(dds::Client& client, FeedOptions options) : client_(client), options_(std::move(options)) {}

Feed::~Feed() { stop(); }

Status Feed::start() {
  auto on_event = [this](const dds::EventSample& e) {
    std::lock_guard lock(inbox_mutex_);
    if (events_in_.size() < 4096) events_in_.push_back(e);
    else ++inbox_dropped_;
  };
  auto on_timing = [this](const dds::TimingSample& t) {
    std::lock_guard lock(inbox_mutex_);
    if (timing_in_.size() < 256) timing_in_.push_back(t);
    else ++inbox_dropped_;
  };
  auto events = client_.subscribe_events(options_.pipeline, on_event);
  if (!events) return events.status();
  pipeline_subscriptions_.push_back(std::move(*events));
  auto timing = client_.subscribe_timing(options_.pipeline, on_timing);
  if (!timing) return timing.status();
  pipeline_subscriptions_.push_back(std::move(*timing));
  refresh_signals();
  batcher_ = std::thread([this] { batch_loop(); });
  return Status::ok();
}

void Feed::stop() {
  {
    std::lock_guard lock(stop_mutex_);
    if (stopping_ && !batcher_.joinable()) return;
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (batcher_.joinable()) batcher_.join();
  {
    std::lock_guard lock(pages_mutex_);
    for (auto& p : pages_) p->close();
    pages_.clear();
  }
  // Unsubscribing waits for a listener in flight: after this no callback touches `this`.
  pipeline_subscriptions_.clear();
  std::lock_guard lock(topics_mutex_);
  for (auto& [name, topic] : topics_) topic->subscription.reset();
}

void Feed::refresh_signals() {
  auto all = client_.signals(std::chrono::milliseconds(0));
  if (!options_.pipeline.empty())
    std::erase_if(all, [&](const dds::SignalMeta& m) { return m.pipeline != options_.pipeline; });
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.topic < b.topic; });
  json list = json::array();
  for (const auto& m : all) list.push_back(signal_json(m));
  std::string text = list.dump();
  {
    std::lock_guard lock(signals_mutex_);
    if (text == signals_json_) return;
    signals_ = std::move(all);
    signals_json_ = text;
  }
  auto message = sse("signals", text);
  {
    std::lock_guard lock(pages_mutex_);
    signals_message_ = message;
  }
  publish(message);
}

std::string Feed::signals_json() const {
  std::lock_guard lock(signals_mutex_);
  return signals_json_;
}

Status Feed::watch(const std::string& topic_name) {
  std::lock_guard lock(topics_mutex_);
  if (topics_.count(topic_name)) return Status::ok();
  std::optional<dds::SignalMeta> meta;
  {
    std::lock_guard signals_lock(signals_mutex_);
    for (const auto& m : signals_)
      if (m.topic == topic_name) meta = m;
  }
  if (!meta) return Status::error("no topic '" + topic_name + "' in lode/signals");
  auto topic = std::make_unique<Topic>();
  topic->meta = *meta;
  topic->width = 2 + meta->names.size();
  topic->pending.reserve(std::min<std::size_t>(options_.max_pending_samples, 1024) * topic->width);
  Topic* raw = topic.get();
  const std::size_t capacity = options_.max_pending_samples * raw->width;
  auto subscription = client_.subscribe(*meta, [raw, capacity](const dds::SignalMeta&, const dds::Sample& s) {
    std::lock_guard topic_lock(raw->mutex);
    ++raw->received;
    if (raw->pending.size() + raw->width > capacity) {
      ++raw->dropped;
      return;
    }
    raw->pending.push_back(static_cast<double>(s.cycle));
    raw->pending.push_back(static_cast<double>(s.stamp_ns) * 1e-9);
    for (std::size_t k = 0; k + 2 < raw->width; ++k)
      raw->pending.push_back(k < s.values.size() ? s.values[k] : std::nan(""));
  });
  if (!subscription) return subscription.status();
  topic->subscription = std::move(*subscription);
  topics_.emplace(topic_name, std::move(topic));
  return Status::ok();
}

std::shared_ptr<PageQueue> Feed::attach() {
  auto page = std::make_shared<PageQueue>(options_.page_queue_messages);
  std::lock_guard lock(pages_mutex_);
  if (signals_message_) page->push(signals_message_);
  for (const auto& e : recent_events_) page->push(e);
  for (const auto& [pipeline, t] : latest_timing_) page->push(t);
  pages_.push_back(page);
  return page;
}

void Feed::detach(const std::shared_ptr<PageQueue>& page) {
  page->close();
  std::lock_guard lock(pages_mutex_);
  closed_pages_dropped_ += page->dropped();
  std::erase(pages_, page);
}

void Feed::publish(std::shared_ptr<const std::string> message) {
  std::lock_guard lock(pages_mutex_);
  for (auto& p : pages_) p->push(message);
}

FeedCounters Feed::counters() const {
  FeedCounters c;
  {
    std::lock_guard lock(topics_mutex_);
    c.topics_watched = topics_.size();
    for (const auto& [name, topic] : topics_) {
      std::lock_guard topic_lock(topic->mutex);
      c.samples_received += topic->received;
      c.samples_dropped += topic->dropped;
    }
  }
  std::lock_guard lock(pages_mutex_);
  c.pages = pages_.size();
  c.messages_dropped = closed_pages_dropped_;
  for (const auto& p : pages_) c.messages_dropped += p->dropped();
  return c;
}

std::shared_ptr<const std::string> Feed::samples_message() {
  std::string data;
  std::vector<double> rows;
  std::lock_guard lock(topics_mutex_);
  for (auto& [name, topic] : topics_) {
    {
      // Swap, not copy: the listener goes on at once with the (emptied) buffer `rows` had.
      std::lock_guard topic_lock(topic->mutex);
      rows.swap(topic->pending);
      topic->pending.clear();
    }
    if (rows.empty()) continue;
    static_assert(std::endian::native == std::endian::little, "the page reads little-endian float64");
    data += data.empty() ? "{\"topics\":[" : ",";
    data += "{\"topic\":" + json(name).dump() + ",\"width\":" + std::to_string(topic->width) +
            ",\"rows\":" + std::to_string(rows.size() / topic->width) + ",\"data\":\"" +
            plot::base64(rows.data(), rows.size() * sizeof(double)) + "\"}";
    rows.clear();
  }
  if (data.empty()) return nullptr;
  data += "]}";
  return sse("samples", data);
}

std::shared_ptr<const std::string> Feed::status_message() const {
  const FeedCounters c = counters();
  std::uint64_t inbox_dropped = 0;
  {
    std::lock_guard lock(inbox_mutex_);
    inbox_dropped = inbox_dropped_;
  }
  const json status = {{"samples_received", c.samples_received},
                       {"samples_dropped", c.samples_dropped + inbox_dropped},
                       {"messages_dropped", c.messages_dropped},
                       {"pages", c.pages},
                       {"topics_watched", c.topics_watched}};
  return sse("status", status.dump());
}

void Feed::batch_loop() {
  auto next_batch = Clock::now();
  auto next_status = next_batch;
  auto next_signals = next_batch + std::chrono::seconds(1);
  std::vector<dds::EventSample> events;
  std::vector<dds::TimingSample> timing;
  for (;;) {
    next_batch += options_.batch_period;
    {
      std::unique_lock lock(stop_mutex_);
      if (stop_cv_.wait_until(lock, next_batch, [&] { return stopping_; })) return;
    }
    const auto now = Clock::now();
    if (now - next_batch > options_.batch_period * 4) next_batch = now;  // a stall: do not burst to catch up

    if (auto samples = samples_message()) publish(std::move(samples));
    {
      std::lock_guard lock(inbox_mutex_);
      events.swap(events_in_);
      timing.swap(timing_in_);
    }
    for (const auto& e : events) {
      const json j = {{"pipeline", e.pipeline}, {"cycle", e.cycle}, {"stamp_s", static_cast<double>(e.stamp_ns) * 1e-9},
                      {"kind", e.kind}, {"text", e.text}};
      auto message = sse("event", j.dump());
      {
        std::lock_guard lock(pages_mutex_);
        recent_events_.push_back(message);
        if (recent_events_.size() > options_.events_kept) recent_events_.pop_front();
      }
      publish(std::move(message));
    }
    for (const auto& t : timing) {
      auto message = sse("timing", timing_json(t).dump());
      {
        std::lock_guard lock(pages_mutex_);
        latest_timing_[t.pipeline] = message;
      }
      publish(std::move(message));
    }
    events.clear();
    timing.clear();
    if (now >= next_status) {
      next_status = now + std::chrono::milliseconds(500);
      publish(status_message());
    }
    if (now >= next_signals) {
      next_signals = now + std::chrono::seconds(1);
      refresh_signals();
    }
  }
}

}  // namespace lode::cli::scope
