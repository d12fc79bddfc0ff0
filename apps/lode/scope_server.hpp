// lode scope's HTTP side (cpp-httplib): the page and its assets, the sample stream
// (Server-Sent Events), the parameter list and the commands, and who may use them.
//
// Access: on a loopback address with no token, only this host reaches the server; a
// command must still come as `Content-Type: application/json` with a loopback Host header,
// so another web site open in the same browser can neither post a plain form to it nor
// reach it by rebinding its own name to 127.0.0.1. Anywhere else a token is required
// (random, printed at start): every request carries it as ?token=, an `X-Lode-Token`
// header, or the cookie the page's first (token-carrying) load sets; without it, 403.
//
// Limits: cpp-httplib serves each connection on a thread of a fixed pool, and a page's stream
// holds its thread for as long as the page is open. So the pool has room for kMaxPages
// streams and kThreadsBesidePages other requests beside them; a stream past kMaxPages gets
// 503 (the page says so and retries), never the last free thread. A request body (a command)
// over kMaxBodyBytes gets 413 before it is held in memory.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <string>

#include "lode/sdk/status.hpp"

namespace httplib {
class Server;
}

namespace lode::cli::scope {

class Feed;
class Commands;

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  ///< 0: any free port (bind() says which)
  std::string token;  ///< empty: no token asked (loopback only)
};

/// "127.0.0.1", "::1", "localhost", any 127.x.y.z.
bool is_loopback(const std::string& host);
/// 32 hex digits from the kernel's random source.
std::string random_token();
/// Splits "HOST:PORT" / "[V6]:PORT"; false when malformed.
bool parse_listen(const std::string& text, std::string& host, int& port);

class Server {
 public:
  static constexpr int kMaxPages = 32;
  static constexpr int kThreadsBesidePages = 16;
  static constexpr std::size_t kMaxBodyBytes = 1 << 20;

  Server(Feed& feed, Commands& commands, ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Binds the address; the port bound (the free one chosen for port 0).
  Expected<int> bind();
  /// Serves until stop() (from another thread).
  void run();
  void stop();

 private:
  void routes();
  [[nodiscard]] bool allowed(const std::string& token_given, const std::string& host_header) const;

  Feed& feed_;
  Commands& commands_;
  const ServerOptions options_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::atomic<int> open_pages_{0};  ///< streams being served
};

}  // namespace lode::cli::scope
