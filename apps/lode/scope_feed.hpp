// lode scope's data side: DDS subscriptions (signals the page watches, every pipeline's events
// and timing) turned into Server-Sent-Event messages for the pages attached.
//
// Two rules keep a slow or absent browser from ever reaching back into the pipeline's
// telemetry: a DDS listener only appends a sample to its topic's bounded pending buffer (a
// short lock shared with nothing but the batching thread; full: the sample is counted as
// dropped, never waited for), and each page has its own bounded queue of formatted messages
// (full: the oldest is dropped and counted). One batching thread, every `batch_period`,
// turns the pending samples into one message per period (so 10 signals at 1 kHz cost ~25
// messages a second, not 10 000) and hands it to every page's queue.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "lode/dds/client.hpp"

namespace lode::cli::scope {

/// One attached page's outgoing messages, each a complete SSE event ("event: X\ndata: ...\n\n").
class PageQueue {
 public:
  explicit PageQueue(std::size_t capacity) : capacity_(capacity) {}
  /// Never waits: a full queue loses its oldest message (counted in dropped()).
  void push(std::shared_ptr<const std::string> message);
  /// The queued messages, waiting up to `wait` for the first one; empty after close().
  std::vector<std::shared_ptr<const std::string>> take(std::chrono::milliseconds wait);
  void close();
  [[nodiscard]] bool closed() const;
  [[nodiscard]] std::uint64_t dropped() const;

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::shared_ptr<const std::string>> messages_;
  std::uint64_t dropped_ = 0;
  bool closed_ = false;
};

struct FeedOptions {
  std::string pipeline;  ///< "" = every pipeline on the domain
  std::chrono::milliseconds batch_period{40};
  /// Per topic, samples waiting for the next batch; a second at 16 kHz, far more than a
  /// 40 ms period needs, so only a stalled batching thread ever drops.
  std::size_t max_pending_samples = 16384;
  std::size_t page_queue_messages = 256;  ///< ~10 s of batches per page
  std::size_t events_kept = 500;          ///< replayed to a page that attaches late
};

/// Counts shown on the page's status strip (the scope's own losses, beside the pipeline's).
struct FeedCounters {
  std::uint64_t samples_received = 0;
  std::uint64_t samples_dropped = 0;  ///< pending buffers full (batching thread too slow)
  std::uint64_t messages_dropped = 0;  ///< page queues full (a browser too slow), all pages
  std::size_t pages = 0;
  std::size_t topics_watched = 0;
};

class Feed {
 public:
  Feed(dds::Client& client, FeedOptions options);
  ~Feed();
  Feed(const Feed&) = delete;
  Feed& operator=(const Feed&) = delete;

  /// Subscribes to the events and timing, starts the batching thread.
  Status start();
  /// Ends every page's stream and the subscriptions.
  void stop();

  /// Starts sending `topic`'s samples (once; later calls are no-ops). Error: not in lode/signals.
  Status watch(const std::string& topic);
  /// The lode/signals metadata as a JSON array (topic, pipeline, block, port, names, units, rate_hz).
  [[nodiscard]] std::string signals_json() const;

  /// A new page stream, primed with the signals, the recent events and the latest timing.
  std::shared_ptr<PageQueue> attach();
  void detach(const std::shared_ptr<PageQueue>& page);

  [[nodiscard]] FeedCounters counters() const;

 private:
  struct Topic;

  void batch_loop();
  void publish(std::shared_ptr<const std::string> message);
  std::shared_ptr<const std::string> samples_message();
  std::shared_ptr<const std::string> status_message() const;
  void refresh_signals();

  dds::Client& client_;
  const FeedOptions options_;

  mutable std::mutex topics_mutex_;  ///< the map, not the buffers (each has its own lock)
  std::map<std::string, std::unique_ptr<Topic>> topics_;

  // Events and timing arrive at a few per second: the listener formats nothing, it queues.
  mutable std::mutex inbox_mutex_;
  std::vector<dds::EventSample> events_in_;
  std::vector<dds::TimingSample> timing_in_;
  std::uint64_t inbox_dropped_ = 0;

  mutable std::mutex pages_mutex_;
  std::vector<std::shared_ptr<PageQueue>> pages_;
  std::deque<std::shared_ptr<const std::string>> recent_events_;
  std::map<std::string, std::shared_ptr<const std::string>> latest_timing_;  ///< per pipeline
  std::shared_ptr<const std::string> signals_message_;
  std::uint64_t closed_pages_dropped_ = 0;

  mutable std::mutex signals_mutex_;
  std::vector<dds::SignalMeta> signals_;
  std::string signals_json_ = "[]";

  std::vector<std::unique_ptr<dds::Subscription>> pipeline_subscriptions_;
  std::thread batcher_;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
};

}  // namespace lode::cli::scope
