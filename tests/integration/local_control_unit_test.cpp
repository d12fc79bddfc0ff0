// The local command channel (apps/lode/local_control.hpp) without `lode run`: the wire
// format's strictness, and a LocalControlServer around a real ControlService and pipeline
// (a sine source with runtime parameters; no RT thread, so commands apply directly).
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "local_control.hpp"
#include "lode/control.hpp"
#include "lode/sdk/diagnostics.hpp"
#include "lode/event_log.hpp"
#include "lode/pipeline.hpp"
#include "lode/plugin_loader.hpp"

namespace {

using lode::ControlReply;
using lode::ControlRequest;
using namespace lode::cli;
using std::chrono::milliseconds;

// --- wire format -------------------------------------------------------------------------
TEST(LocalControlWire, RequestRoundTripKeepsEveryByte) {
  ControlRequest r;
  r.id = std::numeric_limits<std::uint64_t>::max();  // exact: lode::Json would round it
  r.kind = "swap";
  r.block = "obs\"erver\\";
  r.name = "line1\nline2\ttab\x01\x7f";
  r.value = "{d: 0.2, q: [1, 2]}";
  r.plugin = "estimator.ukf \xc2\xb5";  // UTF-8 passes through
  r.client = "me@host";
  const std::string line = encode_request(r);
  EXPECT_EQ(line.find('\n'), std::string::npos) << line;
  auto back = decode_request(line);
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back->id, r.id);
  EXPECT_EQ(back->kind, r.kind);
  EXPECT_EQ(back->block, r.block);
  EXPECT_EQ(back->name, r.name);
  EXPECT_EQ(back->value, r.value);
  EXPECT_EQ(back->plugin, r.plugin);
  EXPECT_EQ(back->client, r.client);
}

TEST(LocalControlWire, ReplyRoundTrip) {
  ControlReply r;
  r.id = 42;
  r.ok = true;
  r.message = "observer.d: 1 -> 0.2 at cycle 812";
  r.value = "a [0, 1]  first\nb [0, 2]  second\n";
  auto back = decode_reply(encode_reply(r));
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back->id, 42u);
  EXPECT_TRUE(back->ok);
  EXPECT_EQ(back->message, r.message);
  EXPECT_EQ(back->value, r.value);
}

TEST(LocalControlWire, ValueMayBeNumberOrBoolAsWritten) {
  auto a = decode_request(R"({"kind": "set", "value": 1e-3})");
  ASSERT_TRUE(a) << a.error();
  EXPECT_EQ(a->value, "1e-3");
  auto b = decode_request(R"( { "kind" : "set" , "value" : false } )");
  ASSERT_TRUE(b) << b.error();
  EXPECT_EQ(b->value, "false");
  auto c = decode_request(R"({"kind": "get", "block": "\u00b5\ud83d\ude00\/"})");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->block, "\xc2\xb5\xf0\x9f\x98\x80/");
  auto d = decode_request(R"({"kind": "status"})");
  ASSERT_TRUE(d) << d.error();
  EXPECT_EQ(d->id, 0u);
}

TEST(LocalControlWire, MalformedRequestsAreRefusedWithWhatAndWhere) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "empty request"},
      {"set observer.d 0.2", "column 1: expected '{'"},
      {R"({"kind": "set",})", "column 16: syntax error while parsing object key"},
      {R"({"kind" "set"})", "column 13: syntax error while parsing object separator"},
      {R"({"kind": "set"} x)", "column 17: syntax error while parsing value - invalid literal"},
      {R"({"kind": "set", "value": [1, 2]})", "nested objects and arrays"},
      {R"({"kind": "set", "value": {"a": 1}})", "nested objects and arrays"},
      {R"({"kind": "set", "value": null})", "\"value\": null is not accepted"},
      {R"({"kind": "set", "bloc": "observer"})", "unknown key \"bloc\""},
      {R"({"kind": "set", "kind": "get"})", "duplicate key \"kind\""},
      {R"({"kind": "set", "block": 3})", "\"block\" must be a string"},
      {R"({"kind": 1})", "\"kind\" must be a string"},
      {R"({"block": "observer"})", "missing \"kind\""},
      {R"({"kind": ""})", "\"kind\" is empty"},
      {R"({"id": -1, "kind": "set"})", "\"id\" must be a non-negative integer"},
      {R"({"id": 1.5, "kind": "set"})", "\"id\" must be a non-negative integer"},
      {R"({"id": 18446744073709551616, "kind": "set"})", "does not fit in 64 bits"},
      {R"({"id": "7", "kind": "set"})", "\"id\" must be a number"},
      {R"({"kind": "se\qt"})", "column 14: syntax error while parsing value - invalid string: forbidden character after backslash"},
      {R"({"kind": "set", "value": "0.2)", "missing closing quote"},
      {"{\"kind\": \"se\tt\"}", "control character U+0009"},
      {R"({"kind": "\ud800"})", "surrogate U+D800..U+DBFF must be followed by U+DC00..U+DFFF"},
      {R"({"kind": "\udc00"})", "surrogate U+DC00..U+DFFF must follow U+D800..U+DBFF"},
      {R"({"kind": "set", "value": 01})", "column 27: syntax error while parsing object"},
      {R"({"kind": "set", "value": -})", "expected digit after '-'"},
      {R"({"kind": "set", "value": 1.})", "expected digit after '.'"},
      {R"({"kind": "set", "value": tru})", "invalid literal"},
      {R"({"kind": "set", "value": )", "unexpected end of input"},
  };
  for (const auto& [line, want] : cases) {
    auto r = decode_request(line);
    ASSERT_FALSE(r) << "accepted: " << line;
    EXPECT_NE(r.error().find(want), std::string::npos) << "line: " << line << "\nerror: " << r.error()
                                                      << "\nwanted: " << want;
  }
}

TEST(LocalControlWire, IdReadBeforeAnErrorIsReturned) {
  std::uint64_t id = 0;
  auto r = decode_request(R"({"id": 99, "kind": "set", "value": [1]})", &id);
  ASSERT_FALSE(r);
  EXPECT_EQ(id, 99u);
}

// --- server ------------------------------------------------------------------------------
const char* kPipeline =
    "pipeline: lc_unit\n"
    "rate_hz: 1000\n"
    "blocks:\n"
    "  wobble:\n"
    "    plugin: source.sine\n"
    "    names: [x]\n"
    "    units: [m]\n"
    "    amplitude: [1.0e-3]\n"
    "    frequency_hz: [5]\n";

class LocalControlServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/lode-lc-unit-XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    root_ = tmpl;
    dir_ = root_ + "/sock";  // created (0700) by the server
    lode::Diagnostics diag;
    pipeline_ = lode::Pipeline::load_text(kPipeline, "lc_unit.yaml", registry_, diag);
    ASSERT_TRUE(pipeline_) << diag.format();
    control_ = std::make_unique<lode::ControlService>(*pipeline_, events_);
    options_.dir = dir_;
  }
  void TearDown() override {
    server_.reset();
    control_.reset();
    pipeline_.reset();
    std::system(("rm -rf " + root_).c_str());
  }
  void start() {
    auto s = LocalControlServer::start(*control_, "lc_unit", options_);
    ASSERT_TRUE(s) << s.error();
    server_ = std::move(*s);
  }
  std::string path() const { return dir_ + "/lc_unit.sock"; }
  ControlReply send(ControlRequest r, milliseconds timeout = milliseconds(3000)) {
    auto reply = local_send(path(), r, timeout);
    EXPECT_TRUE(reply) << reply.error();
    return reply ? *reply : ControlReply{};
  }
  /// A raw client: the test speaks the wire format itself.
  int connect_raw() const {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path().c_str());
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
    timeval tv{5, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return fd;
  }
  static std::string read_line(int fd) {
    std::string line;
    char c;
    while (::recv(fd, &c, 1, 0) == 1 && c != '\n') line.push_back(c);
    return line;
  }
  std::string first_parameter() {
    ControlRequest r;
    r.kind = "list";
    const auto reply = send(r);
    EXPECT_TRUE(reply.ok) << reply.message;
    return reply.value.substr(0, reply.value.find(' '));  // "wobble.xxx"
  }

  std::string root_, dir_;
  lode::PluginRegistry registry_;
  std::unique_ptr<lode::Pipeline> pipeline_;
  lode::EventLog events_;
  std::unique_ptr<lode::ControlService> control_;
  LocalControlOptions options_;
  std::unique_ptr<LocalControlServer> server_;
};

TEST_F(LocalControlServerTest, ListGetSetAndRefusal) {
  start();
  ControlRequest list;
  list.kind = "list";
  list.id = 5;
  const auto l = send(list);
  EXPECT_TRUE(l.ok) << l.message;
  EXPECT_EQ(l.id, 5u);
  EXPECT_NE(l.value.find("wobble."), std::string::npos) << l.value;
  EXPECT_NE(l.message.find("runtime parameter"), std::string::npos) << l.message;

  // amplitude is the second group; its name is whatever the source calls it.
  std::string amplitude;
  for (std::size_t at = 0; at < l.value.size();) {
    const auto end = l.value.find('\n', at);
    const std::string line = l.value.substr(at, end - at);
    if (line.find("amplitude") != std::string::npos) amplitude = line.substr(0, line.find(' '));
    at = end == std::string::npos ? l.value.size() : end + 1;
  }
  ASSERT_FALSE(amplitude.empty()) << l.value;
  ControlRequest set;
  set.kind = "set";
  set.block = amplitude.substr(0, amplitude.find('.'));
  set.name = amplitude.substr(amplitude.find('.') + 1);
  set.value = "0.25";
  const auto s = send(set);
  EXPECT_TRUE(s.ok) << s.message;
  EXPECT_NE(s.message.find("0.001 -> 0.25"), std::string::npos) << s.message;
  EXPECT_EQ(s.value, "0.25");
  // The event log names the local peer (SO_PEERCRED): this process.
  bool named = false;
  for (const auto& e : events_.snapshot())
    named = named || e.text.find("local pid " + std::to_string(::getpid())) != std::string::npos;
  EXPECT_TRUE(named);

  set.value = "banana";
  const auto bad = send(set);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.message.find("'banana' is not a number"), std::string::npos) << bad.message;

  ControlRequest unknown;
  unknown.kind = "frobnicate";
  const auto u = send(unknown);
  EXPECT_FALSE(u.ok);
  EXPECT_NE(u.message.find("unknown command kind 'frobnicate'"), std::string::npos) << u.message;
}

TEST_F(LocalControlServerTest, MalformedLineGetsAReplyAndTheConnectionStays) {
  start();
  const int fd = connect_raw();
  const std::string lines = "not json at all\n\n{\"id\": 12, \"kind\": \"status\"}\r\n{\"id\": 13, \"kind\": \"set\", \"x\": 1}\n";
  ASSERT_EQ(::send(fd, lines.data(), lines.size(), 0), static_cast<ssize_t>(lines.size()));
  auto first = decode_reply(read_line(fd));
  ASSERT_TRUE(first) << first.error();
  EXPECT_FALSE(first->ok);
  EXPECT_EQ(first->id, 0u);
  EXPECT_NE(first->message.find("malformed request: column 1: expected '{'"), std::string::npos) << first->message;
  auto second = decode_reply(read_line(fd));  // the blank line got no reply
  ASSERT_TRUE(second) << second.error();
  EXPECT_TRUE(second->ok) << second->message;
  EXPECT_EQ(second->id, 12u);
  EXPECT_NE(second->message.find("pipeline 'lc_unit'"), std::string::npos) << second->message;
  auto third = decode_reply(read_line(fd));
  ASSERT_TRUE(third) << third.error();
  EXPECT_FALSE(third->ok);
  EXPECT_EQ(third->id, 13u);
  EXPECT_NE(third->message.find("unknown key \"x\""), std::string::npos) << third->message;
  // A last request without newline, then end of input: still answered.
  const std::string last = "{\"id\": 14, \"kind\": \"status\"}";
  ASSERT_EQ(::send(fd, last.data(), last.size(), 0), static_cast<ssize_t>(last.size()));
  ::shutdown(fd, SHUT_WR);
  auto fourth = decode_reply(read_line(fd));
  ASSERT_TRUE(fourth) << fourth.error();
  EXPECT_EQ(fourth->id, 14u);
  ::close(fd);
  const auto st = server_->stats();
  EXPECT_EQ(st.malformed, 2u);
  EXPECT_EQ(st.requests, 2u);
}

TEST_F(LocalControlServerTest, ConcurrentClientsAreAllServed) {
  start();
  const std::string param = first_parameter();
  constexpr int kClients = 8, kEach = 40;
  std::vector<std::thread> threads;
  std::atomic<int> good{0};
  for (int c = 0; c < kClients; ++c) {
    threads.emplace_back([&, c] {
      for (int k = 0; k < kEach; ++k) {
        ControlRequest r;
        r.kind = "get";
        r.block = param.substr(0, param.find('.'));
        r.name = param.substr(param.find('.') + 1);
        r.id = static_cast<std::uint64_t>(c * 1000 + k + 1);
        auto reply = local_send(path(), r, milliseconds(10000));
        if (reply && reply->ok && reply->id == r.id) good.fetch_add(1);
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(good.load(), kClients * kEach);
  EXPECT_GE(server_->stats().requests, static_cast<std::uint64_t>(kClients * kEach));
}

TEST_F(LocalControlServerTest, FilesArePrivate) {
  start();
  struct stat d {}, s {};
  ASSERT_EQ(::stat(dir_.c_str(), &d), 0);
  ASSERT_EQ(::lstat(path().c_str(), &s), 0);
  EXPECT_EQ(d.st_mode & 0777, 0700u);
  EXPECT_TRUE(S_ISSOCK(s.st_mode));
  EXPECT_EQ(s.st_mode & 0777, 0600u);
}

TEST_F(LocalControlServerTest, MissingParentsAreCreatedPrivate) {
  options_.dir = root_ + "/fresh/xdg/lode";  // XDG_RUNTIME_DIR pointed at a path not made yet
  start();
  struct stat st {};
  ASSERT_EQ(::stat((root_ + "/fresh/xdg").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  EXPECT_TRUE(probe_local_socket(root_ + "/fresh/xdg/lode/lc_unit.sock"));
}

TEST_F(LocalControlServerTest, SecondRunOfTheSamePipelineIsRefused) {
  start();
  auto second = LocalControlServer::start(*control_, "lc_unit", options_);
  ASSERT_FALSE(second);
  EXPECT_NE(second.error().find("pipeline lc_unit is already running locally (pid " + std::to_string(::getpid()) + ","),
            std::string::npos)
      << second.error();
  // The first one still serves.
  ControlRequest r;
  r.kind = "status";
  EXPECT_TRUE(send(r).ok);
}

TEST_F(LocalControlServerTest, StaleSocketIsDetectedAndReplaced) {
  ASSERT_EQ(::mkdir(dir_.c_str(), 0700), 0);
  {  // what a crashed run leaves: a bound socket file nobody listens on
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path().c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    ::close(fd);
  }
  ControlRequest r;
  r.kind = "status";
  auto before = local_send(path(), r, milliseconds(1000));
  ASSERT_FALSE(before);
  EXPECT_NE(before.error().find("is stale: nothing listens there"), std::string::npos) << before.error();
  EXPECT_FALSE(probe_local_socket(path()));
  start();
  EXPECT_TRUE(server_->replaced_stale());
  EXPECT_TRUE(send(r).ok);
  const auto pid = probe_local_socket(path());
  ASSERT_TRUE(pid);
  EXPECT_EQ(*pid, ::getpid());
}

TEST_F(LocalControlServerTest, NotASocketOrAPublicDirectoryIsRefused) {
  ASSERT_EQ(::mkdir(dir_.c_str(), 0700), 0);
  std::ofstream(path()) << "not a socket\n";
  auto a = LocalControlServer::start(*control_, "lc_unit", options_);
  ASSERT_FALSE(a);
  EXPECT_NE(a.error().find("exists and is not a socket; not touching it"), std::string::npos) << a.error();
  ::unlink(path().c_str());
  ASSERT_EQ(::chmod(dir_.c_str(), 0755), 0);
  auto b = LocalControlServer::start(*control_, "lc_unit", options_);
  ASSERT_FALSE(b);
  EXPECT_NE(b.error().find("has mode 0755"), std::string::npos) << b.error();
  auto c = LocalControlServer::start(*control_, "../evil", options_);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().find("cannot name a socket file"), std::string::npos) << c.error();
}

TEST_F(LocalControlServerTest, StopIsPromptWithIdleClientsAndRemovesTheSocket) {
  start();
  const int idle = connect_raw();  // connected, sends nothing
  ControlRequest r;
  r.kind = "status";
  EXPECT_TRUE(send(r).ok);
  const auto t0 = std::chrono::steady_clock::now();
  server_->stop();
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("stop() with one idle client took %.3f ms\n", stop_s * 1e3);
  EXPECT_LT(stop_s, 2.0);  // loose: it waits on poll(), not on a timeout
  struct stat st {};
  EXPECT_NE(::lstat(path().c_str(), &st), 0) << "socket file left behind";
  char c;
  EXPECT_EQ(::recv(idle, &c, 1, 0), 0);  // the idle client sees end of stream
  ::close(idle);
  auto after = local_send(path(), r, milliseconds(500));
  ASSERT_FALSE(after);
  EXPECT_NE(after.error().find("no local pipeline at"), std::string::npos) << after.error();
  server_->stop();  // idempotent
  // The lock was released: a new run of the pipeline starts.
  start();
  EXPECT_FALSE(server_->replaced_stale());
}

TEST_F(LocalControlServerTest, OverlongLineAndTooManyClientsAreRefused) {
  options_.max_clients = 2;
  options_.max_line = 1024;
  start();
  const int a = connect_raw(), b = connect_raw();
  const std::string status = "{\"kind\": \"status\"}\n";
  for (int fd : {a, b}) {
    ASSERT_EQ(::send(fd, status.data(), status.size(), 0), static_cast<ssize_t>(status.size()));
    auto r = decode_reply(read_line(fd));  // now both are accepted
    ASSERT_TRUE(r && r->ok);
  }
  const int c = connect_raw();
  auto refused = decode_reply(read_line(c));
  ASSERT_TRUE(refused) << refused.error();
  EXPECT_FALSE(refused->ok);
  EXPECT_NE(refused->message.find("too many local clients (2 connected)"), std::string::npos) << refused->message;
  ::close(c);

  const std::string big(4096, 'x');
  ASSERT_EQ(::send(a, big.data(), big.size(), 0), static_cast<ssize_t>(big.size()));
  auto longline = decode_reply(read_line(a));
  ASSERT_TRUE(longline) << longline.error();
  EXPECT_NE(longline->message.find("longer than 1024 bytes"), std::string::npos) << longline->message;
  char ch;
  EXPECT_EQ(::recv(a, &ch, 1, 0), 0);  // and the connection is closed
  ::close(a);
  ::close(b);
  EXPECT_EQ(server_->stats().refused_clients, 2u);
}

TEST_F(LocalControlServerTest, IdleClientsAreDroppedAndABusyServerSaysSo) {
  // Idle connections used to hold every slot for ever, and `lode set` then failed with
  // "Broken pipe". Now a client at the limit is told "busy", and idle ones are dropped.
  options_.max_clients = 2;
  options_.idle_timeout = milliseconds(300);
  start();
  const int a = connect_raw(), b = connect_raw();  // connected, silent
  ControlRequest r;
  r.kind = "status";
  std::this_thread::sleep_for(milliseconds(50));  // both accepted
  // The refusal arrives as the reply (the request was already sent) or, when the server had
  // closed first, as the error of the send: either way it says "busy".
  auto busy = local_send(path(), r, milliseconds(200));
  ASSERT_FALSE(busy && busy->ok) << "a third client was served past max_clients = 2";
  const std::string refusal = busy ? busy->message : busy.error();
  EXPECT_NE(refusal.find("busy: too many local clients (2 connected)"), std::string::npos) << refusal;
  EXPECT_EQ(refusal.find("Broken pipe"), std::string::npos) << refusal;
  // Past the idle timeout both idle clients are told why and disconnected...
  for (int fd : {a, b}) {
    auto said = decode_reply(read_line(fd));
    ASSERT_TRUE(said) << said.error();
    EXPECT_NE(said->message.find("idle for 300 ms"), std::string::npos) << said->message;
    char ch;
    EXPECT_EQ(::recv(fd, &ch, 1, 0), 0);
    ::close(fd);
  }
  // ...and a command gets through again.
  EXPECT_TRUE(send(r).ok);
  EXPECT_EQ(server_->stats().idle_closed, 2u);
}

// Without XDG_RUNTIME_DIR or a /run/user directory, the socket goes to /tmp/lode-<uid>. /tmp
// is shared: another local user can create that name first (as a directory of theirs or a
// symlink to one). The run must neither use it nor be locked out.
TEST_F(LocalControlServerTest, ANameInTmpThatAnotherUserTookIsNotUsedAndDoesNotLockUsOut) {
  RuntimeDirInputs in;
  in.run_user_root = root_ + "/run-user";  // absent: a host without logind's directory
  in.tmp = root_ + "/tmp";
  in.home = root_ + "/home";
  in.uid = ::geteuid();
  ASSERT_EQ(::mkdir(in.tmp.c_str(), 01777), 0);
  ASSERT_EQ(::mkdir(in.home.c_str(), 0700), 0);
  const std::string in_tmp = in.tmp + "/lode-" + std::to_string(in.uid);

  // Nobody took it: /tmp/lode-<uid>, created private by the server.
  EXPECT_EQ(local_control_dir(in), in_tmp);

  // Somebody else's symlink of that name (any user can make one; its owner is not us).
  ASSERT_EQ(::mkdir((root_ + "/elsewhere").c_str(), 0777), 0);
  ASSERT_EQ(::symlink((root_ + "/elsewhere").c_str(), in_tmp.c_str()), 0);
  EXPECT_EQ(local_control_dir(in), in.home + "/.lode/run") << "a symlink in /tmp must not be followed";
  ASSERT_EQ(::unlink(in_tmp.c_str()), 0);

  // Another user's directory of that name (needs root to stage: chown to nobody).
  if (::geteuid() == 0) {
    ASSERT_EQ(::mkdir(in_tmp.c_str(), 0700), 0);
    ASSERT_EQ(::chown(in_tmp.c_str(), 65534, 65534), 0);
    EXPECT_EQ(local_control_dir(in), in.home + "/.lode/run");
    // The server starts there, private, and a client computing the same inputs finds it.
    options_.dir = local_control_dir(in);
    start();
    struct stat st {};
    ASSERT_EQ(::lstat(options_.dir.c_str(), &st), 0);
    EXPECT_EQ(st.st_uid, ::geteuid());
    EXPECT_EQ(st.st_mode & 0777, 0700u);
    ControlRequest r;
    r.kind = "status";
    auto reply = local_send(local_control_dir(in) + "/lc_unit.sock", r, milliseconds(3000));
    ASSERT_TRUE(reply) << reply.error();
    EXPECT_TRUE(reply->ok);
  }

  // Our own /tmp/lode-<uid> with a loose mode stays the answer: the server then says how to fix it.
  std::system(("rm -rf " + in_tmp).c_str());
  ASSERT_EQ(::mkdir(in_tmp.c_str(), 0755), 0);
  EXPECT_EQ(local_control_dir(in), in_tmp);

  // XDG_RUNTIME_DIR, when set, wins over everything.
  in.xdg_runtime_dir = root_ + "/xdg";
  EXPECT_EQ(local_control_dir(in), root_ + "/xdg/lode");
}

TEST(LocalControlClient, TimesOutWhenNobodyAnswers) {
  char tmpl[] = "/tmp/lode-lc-mute-XXXXXX";
  ASSERT_NE(::mkdtemp(tmpl), nullptr);
  const std::string path = std::string(tmpl) + "/mute.sock";
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);  // listens, never accepts nor replies
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 4), 0);
  ControlRequest r;
  r.kind = "status";
  const auto t0 = std::chrono::steady_clock::now();
  auto reply = local_send(path, r, milliseconds(300));
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(reply);
  EXPECT_NE(reply.error().find("no reply from " + path + " within 300 ms"), std::string::npos) << reply.error();
  EXPECT_GE(took, 0.29);
  ::close(fd);
  std::system((std::string("rm -rf ") + tmpl).c_str());
}

}  // namespace
