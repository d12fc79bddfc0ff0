// A badly behaved subscriber: joins the domain, subscribes to every lodestone signal,
// stalls (sleeps in its listener) on every other round, and leaves, `rounds` times.
// The telemetry churn test runs it against a pipeline and checks that the pipeline's
// outputs and overrun count do not change.
//
// usage: telemetry_churn_client DOMAIN ROUNDS
//
// SIGTERM or SIGINT ends it after the current round, its participant deleted: a process killed
// with its participant open leaves its shared memory in /dev/shm.
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "lode/dds/client.hpp"

namespace {
volatile std::sig_atomic_t g_stop = 0;
void request_stop(int) { g_stop = 1; }
}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s DOMAIN ROUNDS\n", argv[0]);
    return 2;
  }
  const int domain = std::atoi(argv[1]);
  const int rounds = std::atoi(argv[2]);
  std::uint64_t samples = 0;
  int rounds_with_data = 0;
  std::signal(SIGTERM, request_stop);
  std::signal(SIGINT, request_stop);
  int round = 0;
  for (; round < rounds && g_stop == 0; ++round) {
    lode::dds::ParticipantOptions o;
    o.domain = domain;
    o.name = "churn-" + std::to_string(round);
    auto client = lode::dds::Client::create(o);
    if (!client) {
      std::fprintf(stderr, "churn: %s\n", client.error().c_str());
      return 1;
    }
    const bool stall = round % 2 == 1;
    std::atomic<std::uint64_t> got{0};
    std::vector<std::unique_ptr<lode::dds::Subscription>> subs;
    for (const auto& meta : (*client)->signals(std::chrono::milliseconds(3000))) {
      auto sub = (*client)->subscribe(meta, [&](const lode::dds::SignalMeta&, const lode::dds::Sample&) {
        got.fetch_add(1);
        // A stalled reader: 20 ms per sample, far slower than the publisher.
        if (stall) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      });
      if (sub) subs.push_back(std::move(*sub));
    }
    // Hold until data flows (discovery takes tens of ms), then a little longer.
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (got.load() == 0 && std::chrono::steady_clock::now() < give_up)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    std::this_thread::sleep_for(std::chrono::milliseconds(20 + 20 * (round % 3)));
    subs.clear();  // leave (mid-stall on stalled rounds)
    client->reset();
    samples += got.load();
    if (got.load() > 0) ++rounds_with_data;
  }
  std::printf("churn: %d rounds, %d with data, %llu samples\n", round, rounds_with_data,
              static_cast<unsigned long long>(samples));
  return 0;
}
