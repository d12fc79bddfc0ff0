// lode scope: a live web page of the pipelines on a DDS domain (signals as rolling or
// triggered plots, timing, events, shadows' health, runtime parameters, swap and promote),
// served from this process so that any browser that reaches it, on any machine of the
// domain, needs nothing installed.
//
// scope_feed turns the DDS subscriptions into batched Server-Sent Events, scope_commands
// sends the page's commands as lode set / lode swap would, scope_server serves it all.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <thread>

#include "commands.hpp"
#include "remote_client.hpp"
#include "scope_commands.hpp"
#include "scope_feed.hpp"
#include "scope_server.hpp"

namespace lode::cli {
namespace {

int scope_main(const Args& args) {
  scope::ServerOptions server_options;
  if (args.has("--listen") &&
      !scope::parse_listen(args.option("--listen"), server_options.host, server_options.port)) {
    std::fprintf(stderr, "lode: --listen wants HOST:PORT (e.g. 127.0.0.1:8080, 0.0.0.0:8080), got '%s'\n",
                 args.option("--listen").c_str());
    return kExitConfig;
  }
  // Off this host, anyone who reaches the port could change parameters: a token then.
  if (!scope::is_loopback(server_options.host) || args.has_flag("--require-token")) {
    server_options.token = scope::random_token();
    if (server_options.token.empty()) {
      std::fprintf(stderr, "lode: scope: cannot read /dev/urandom for the access token\n");
      return kExitFault;
    }
  }

  auto client = make_client(args, "scope");
  if (!client) return kExitConfig;
  scope::FeedOptions feed_options;
  feed_options.pipeline = args.option("--pipeline");
  feed_options.batch_period = milliseconds(args.integer("--batch-ms", 40));
  scope::Feed feed(*client, feed_options);
  if (auto started = feed.start(); !started) {
    std::fprintf(stderr, "lode: scope: %s\n", started.message().c_str());
    return kExitFault;
  }
  scope::Commands commands(*client, feed_options.pipeline,
                           milliseconds(std::llround(args.number("--timeout", 5.0) * 1e3)));
  scope::Server server(feed, commands, server_options);
  auto port = server.bind();
  if (!port) {
    std::fprintf(stderr, "lode: scope: %s\n", port.error().c_str());
    return kExitFault;
  }
  const std::string query = server_options.token.empty() ? "" : "?token=" + server_options.token;
  const std::string& host = server_options.host;
  if (host == "0.0.0.0" || host == "::") {
    // Every interface: 0.0.0.0 is where it listens, not an address a browser can go to. Say
    // this machine's name, and the address that reaches it from here.
    char name[256] = "HOST";
    gethostname(name, sizeof name - 1);
    const std::string loopback = host == "::" ? "[::1]" : "127.0.0.1";
    std::printf("lode scope: http://%s:%d/%s\n", name, *port, query.c_str());
    std::printf("lode scope: listening on every interface (%s); from this machine: http://%s:%d/%s\n", host.c_str(),
                loopback.c_str(), *port, query.c_str());
  } else {
    const bool v6 = host.find(':') != std::string::npos;
    std::printf("lode scope: http://%s:%d/%s\n", (v6 ? "[" + host + "]" : host).c_str(), *port, query.c_str());
  }
  std::fflush(stdout);

  install_stop_handlers();
  std::thread http([&] { server.run(); });
  StopWatch watch(args.number("--duration", 0.0));  // Ctrl-C or --duration
  while (watch.reason().empty())
    std::this_thread::sleep_for(milliseconds(100));
  feed.stop();  // ends the page streams first, so the HTTP threads can return
  server.stop();
  http.join();
  const auto c = feed.counters();
  std::fprintf(stderr, "lode scope: %llu samples received, %llu dropped by the scope, %llu page messages dropped\n",
               static_cast<unsigned long long>(c.samples_received), static_cast<unsigned long long>(c.samples_dropped),
               static_cast<unsigned long long>(c.messages_dropped));
  report_malformed(*client, "scope");
  return kExitOk;
}

}  // namespace

Command scope_command() {
  return {"scope", "a live web page of the pipelines: plots with trigger and cursors, timing, events, parameters, swap",
          [](Declare& d) {
            d.text("--listen", "HOST:PORT",
                   "where to serve the page (default 127.0.0.1:8080; port 0: any free one, printed); "
                   "an address other than loopback requires the printed token");
            d.flag("--require-token", "require the token on loopback too");
            d.text("--pipeline", "NAME", "only this pipeline (default: every pipeline on the domain)");
            d.integer("--batch-ms", "MS", "how often samples are sent to the page (default 40)", 10, 1000);
            d.number("--timeout", "S", "how long a command waits for the pipeline's reply (default 5)", 0.01, 600);
            d.number("--duration", "S", "stop after S seconds (default: until Ctrl-C)", 0, 1e9);
            d.dds_options();
          },
          scope_main};
}

}  // namespace lode::cli
