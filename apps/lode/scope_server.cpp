#include "scope_server.hpp"

#include <httplib.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "plot_assets.hpp"   // uPlot, as compiled into lode plot's reports
#include "scope_assets.hpp"  // the page, its script and style
#include "scope_commands.hpp"
#include "scope_feed.hpp"

namespace lode::cli::scope {

using nlohmann::json;

bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

std::string random_token() {
  unsigned char bytes[16] = {};
  std::ifstream random("/dev/urandom", std::ios::binary);
  random.read(reinterpret_cast<char*>(bytes), sizeof bytes);
  if (!random) return "";  // the caller refuses to serve rather than use a guessable token
  std::string hex;
  char digits[3];
  for (unsigned char b : bytes) {
    std::snprintf(digits, sizeof digits, "%02x", b);
    hex += digits;
  }
  return hex;
}

bool parse_listen(const std::string& text, std::string& host, int& port) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) return false;
  host = text.substr(0, colon);
  if (host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  const std::string digits = text.substr(colon + 1);
  if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 5) return false;
  port = std::stoi(digits);
  return !host.empty() && port <= 65535;
}

namespace {

/// Compares without stopping at the first difference, so response times say nothing about
/// how much of a guessed token was right.
bool same_token(const std::string& given, const std::string& expected) {
  if (given.size() != expected.size()) return false;
  unsigned char difference = 0;
  for (std::size_t i = 0; i < given.size(); ++i)
    difference |= static_cast<unsigned char>(given[i] ^ expected[i]);
  return difference == 0;
}

std::string cookie_value(const std::string& cookies, const std::string& name) {
  std::size_t at = 0;
  while (at < cookies.size()) {
    while (at < cookies.size() && (cookies[at] == ' ' || cookies[at] == ';')) ++at;
    const auto end = cookies.find(';', at);
    const std::string pair = cookies.substr(at, end == std::string::npos ? std::string::npos : end - at);
    if (pair.rfind(name + "=", 0) == 0) return pair.substr(name.size() + 1);
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return "";
}

/// The host part of a Host header ("127.0.0.1:8080", "[::1]:8080", "localhost").
std::string host_of(const std::string& header) {
  if (!header.empty() && header.front() == '[') return header.substr(1, header.find(']') - 1);
  return header.substr(0, header.find(':'));
}

void send_json(httplib::Response& res, const std::string& body) {
  res.set_header("Cache-Control", "no-store");
  res.set_content(body, "application/json");
}

}  // namespace

Server::Server(Feed& feed, Commands& commands, ServerOptions options)
    : feed_(feed), commands_(commands), options_(std::move(options)), http_(std::make_unique<httplib::Server>()) {
  http_->new_task_queue = [] { return new httplib::ThreadPool(kMaxPages + kThreadsBesidePages); };
  http_->set_payload_max_length(kMaxBodyBytes);
  routes();
}

Server::~Server() = default;

bool Server::allowed(const std::string& token_given, const std::string& host_header) const {
  if (!options_.token.empty()) return same_token(token_given, options_.token);
  return is_loopback(host_of(host_header));
}

void Server::routes() {
  http_->set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    std::string token = req.get_param_value("token");
    if (token.empty()) token = req.get_header_value("X-Lode-Token");
    // Cookies are per host, not per port: the name carries the port so that two scopes on
    // one host keep their own.
    if (token.empty()) token = cookie_value(req.get_header_value("Cookie"), "lode_scope_token_" + std::to_string(port_));
    if (!allowed(token, req.get_header_value("Host"))) {
      res.status = 403;
      res.set_content(options_.token.empty() ? "forbidden: not a loopback Host\n"
                                             : "forbidden: this lode scope needs its token (printed at its start)\n",
                      "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.method == "POST" && req.get_header_value("Content-Type").rfind("application/json", 0) != 0) {
      res.status = 415;
      res.set_content("commands are JSON (Content-Type: application/json)\n", "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (!options_.token.empty() && !req.get_param_value("token").empty())
      res.set_header("Set-Cookie", "lode_scope_token_" + std::to_string(port_) + "=" + options_.token +
                                       "; Path=/; HttpOnly; SameSite=Strict");
    return httplib::Server::HandlerResponse::Unhandled;
  });

  auto asset = [this](const std::string& path, std::string_view content, const char* type) {
    http_->Get(path, [content, type](const httplib::Request&, httplib::Response& res) {
      res.set_content(content.data(), content.size(), type);
    });
  };
  asset("/", assets::kScopeHtml, "text/html; charset=utf-8");
  asset("/scope.js", assets::kScopeJs, "text/javascript; charset=utf-8");
  asset("/scope.css", assets::kScopeCss, "text/css; charset=utf-8");
  asset("/uplot.js", plot::assets::kUplotJs, "text/javascript; charset=utf-8");
  asset("/uplot.css", plot::assets::kUplotCss, "text/css; charset=utf-8");

  http_->Get("/api/signals", [this](const httplib::Request&, httplib::Response& res) {
    send_json(res, feed_.signals_json());
  });
  http_->Post("/api/watch", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    json errors = json::array();
    if (body.is_object() && body.contains("topics") && body["topics"].is_array()) {
      for (const auto& topic : body["topics"])
        if (topic.is_string())
          if (auto watched = feed_.watch(topic.get<std::string>()); !watched) errors.push_back(watched.message());
    } else {
      errors.push_back("expected {\"topics\": [...]}");
    }
    send_json(res, json{{"ok", errors.empty()}, {"errors", errors}}.dump());
  });
  http_->Get("/api/parameters", [this](const httplib::Request& req, httplib::Response& res) {
    send_json(res, commands_.parameters(req.get_param_value("pipeline")));
  });
  http_->Post("/api/command", [this](const httplib::Request& req, httplib::Response& res) {
    send_json(res, commands_.run(req.body));
  });
  http_->Get("/api/counters", [this](const httplib::Request&, httplib::Response& res) {
    const FeedCounters c = feed_.counters();
    send_json(res, json{{"samples_received", c.samples_received}, {"samples_dropped", c.samples_dropped},
                        {"messages_dropped", c.messages_dropped}, {"pages", c.pages},
                        {"topics_watched", c.topics_watched}}.dump());
  });
  http_->Get("/api/stream", [this](const httplib::Request&, httplib::Response& res) {
    if (open_pages_.fetch_add(1) >= kMaxPages) {
      open_pages_.fetch_sub(1);
      res.status = 503;
      res.set_header("Retry-After", "5");
      res.set_content("lode scope: " + std::to_string(kMaxPages) +
                          " pages are open already; close one (this page retries every 5 s)\n",
                      "text/plain");
      return;
    }
    auto page = feed_.attach();
    res.set_header("Cache-Control", "no-store");
    res.set_chunked_content_provider(
        "text/event-stream",
        [page, idle = 0](std::size_t offset, httplib::DataSink& sink) mutable {
          if (offset == 0) {
            static constexpr std::string_view kRetry = "retry: 1000\n\n";  // reconnect within a second
            if (!sink.write(kRetry.data(), kRetry.size())) return false;
          }
          // Waits here, on the HTTP thread serving this page: never on a DDS listener.
          const auto messages = page->take(std::chrono::milliseconds(250));
          if (page->closed()) return false;
          for (const auto& m : messages)
            if (!sink.write(m->data(), m->size())) return false;
          // A comment line each second of silence: a proxy or the browser would close a silent
          // stream, and a write is how a page that was closed is noticed (its second write
          // fails) and its place freed.
          if (!messages.empty()) idle = 0;
          else if (++idle % 4 == 0) return sink.write(": idle\n\n", 9);
          return true;
        },
        [this, page](bool) {
          feed_.detach(page);
          open_pages_.fetch_sub(1);
        });
  });
}

Expected<int> Server::bind() {
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(options_.host);
    if (port_ <= 0) return Status::error("cannot listen on " + options_.host + " (any port)");
  } else {
    if (!http_->bind_to_port(options_.host, options_.port))
      return Status::error("cannot listen on " + options_.host + ":" + std::to_string(options_.port) +
                           " (in use, or not an address of this host)");
    port_ = options_.port;
  }
  return port_;
}

void Server::run() { http_->listen_after_bind(); }

void Server::stop() { http_->stop(); }

}  // namespace lode::cli::scope
