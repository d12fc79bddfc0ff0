#include "local_control.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>

namespace lode::cli {

namespace {

using Clock = std::chrono::steady_clock;

std::string errno_text(int e) { return std::strerror(e); }

// ---------------------------------------------------------------------------------------
// A strict parser for one flat JSON object (RFC 8259 strings, numbers, true/false).
// Nothing else in the project parses JSON (lode::Json only writes), and the wire format is
// deliberately flat, so ~150 lines beat a dependency.
struct Scalar {
  enum class Kind { string, number, boolean } kind = Kind::string;
  std::string text;  ///< string: decoded; number: the token as written; boolean: "true"/"false"
  std::size_t column = 0;
};
struct Member {
  std::string key;
  Scalar value;
  std::size_t column = 0;
};

class FlatParser {
 public:
  explicit FlatParser(const std::string& s) : s_(s) {}

  bool parse(std::vector<Member>& out) {
    ws();
    if (!eat('{')) return fail(at_end() ? "empty request (expected a JSON object)" : "expected '{' (a request is one JSON object per line)");
    ws();
    if (eat('}')) return finish();
    for (;;) {
      ws();
      Member m;
      m.column = i_ + 1;
      if (peek() != '"') return fail("expected a key in double quotes");
      if (!string(m.key)) return false;
      ws();
      if (!eat(':')) return fail("expected ':' after key \"" + m.key + "\"");
      ws();
      m.value.column = i_ + 1;
      if (!value(m.key, m.value)) return false;
      out.push_back(std::move(m));
      ws();
      if (eat('}')) return finish();
      if (!eat(',')) return fail("expected ',' or '}' after the value of \"" + out.back().key + "\"");
    }
  }
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  bool finish() {
    ws();
    if (!at_end()) return fail("unexpected text after the closing '}' (one object per line)");
    return true;
  }
  bool value(const std::string& key, Scalar& v) {
    const char c = peek();
    if (c == '"') {
      v.kind = Scalar::Kind::string;
      return string(v.text);
    }
    if (c == '-' || (c >= '0' && c <= '9')) {
      v.kind = Scalar::Kind::number;
      return number(v.text);
    }
    if (literal("true")) {
      v.kind = Scalar::Kind::boolean;
      v.text = "true";
      return true;
    }
    if (literal("false")) {
      v.kind = Scalar::Kind::boolean;
      v.text = "false";
      return true;
    }
    if (literal("null")) return fail("\"" + key + "\": null is not accepted (leave the key out instead)", i_ - 4);
    if (c == '{' || c == '[')
      return fail("\"" + key + "\": nested objects and arrays are not accepted (a flat object of strings, numbers and booleans)");
    if (at_end()) return fail("the line ends before the value of \"" + key + "\"");
    return fail("\"" + key + "\": expected a string, number, true or false");
  }
  bool string(std::string& out) {
    ++i_;  // opening quote
    for (;;) {
      if (at_end()) return fail("unterminated string");
      const auto c = static_cast<unsigned char>(s_[i_]);
      if (c == '"') {
        ++i_;
        return true;
      }
      if (c < 0x20) return fail("control character 0x" + hex2(c) + " inside a string (escape it)");
      if (c != '\\') {
        out.push_back(static_cast<char>(c));
        ++i_;
        continue;
      }
      ++i_;
      if (at_end()) return fail("unterminated escape");
      const char e = s_[i_++];
      switch (e) {
        case '"': out.push_back('"'); break;
        case '\\': out.push_back('\\'); break;
        case '/': out.push_back('/'); break;
        case 'b': out.push_back('\b'); break;
        case 'f': out.push_back('\f'); break;
        case 'n': out.push_back('\n'); break;
        case 'r': out.push_back('\r'); break;
        case 't': out.push_back('\t'); break;
        case 'u': {
          unsigned cp = 0;
          if (!hex4(cp)) return false;
          if (cp >= 0xD800 && cp <= 0xDBFF) {  // surrogate pair (RFC 8259 §7)
            unsigned lo = 0;
            if (!(eat('\\') && eat('u'))) return fail("high surrogate \\u" + hex_of(cp) + " without its low half");
            if (!hex4(lo)) return false;
            if (lo < 0xDC00 || lo > 0xDFFF) return fail("\\u" + hex_of(lo) + " is not a low surrogate");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          } else if (cp >= 0xDC00 && cp <= 0xDFFF) {
            return fail("lone low surrogate \\u" + hex_of(cp));
          }
          utf8(cp, out);
          break;
        }
        default: return fail(std::string("invalid escape '\\") + e + "'", i_ - 2);
      }
    }
  }
  // RFC 8259 §6: -?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?
  bool number(std::string& out) {
    const std::size_t start = i_;
    eat('-');
    if (eat('0')) {
    } else if (digit()) {
      while (digit()) {}
    } else {
      return fail("malformed number");
    }
    if (eat('.')) {
      if (!digit()) return fail("malformed number (digits must follow '.')");
      while (digit()) {}
    }
    if (peek() == 'e' || peek() == 'E') {
      ++i_;
      if (!eat('+')) eat('-');
      if (!digit()) return fail("malformed number (digits must follow the exponent)");
      while (digit()) {}
    }
    out = s_.substr(start, i_ - start);
    return true;
  }
  bool hex4(unsigned& v) {
    v = 0;
    for (int k = 0; k < 4; ++k) {
      if (at_end()) return fail("\\u needs four hex digits");
      const char c = s_[i_];
      unsigned d = 0;
      if (c >= '0' && c <= '9') d = static_cast<unsigned>(c - '0');
      else if (c >= 'a' && c <= 'f') d = static_cast<unsigned>(c - 'a' + 10);
      else if (c >= 'A' && c <= 'F') d = static_cast<unsigned>(c - 'A' + 10);
      else return fail("\\u needs four hex digits");
      v = v * 16 + d;
      ++i_;
    }
    return true;
  }
  static void utf8(unsigned cp, std::string& out) {
    if (cp < 0x80) {
      out.push_back(static_cast<char>(cp));
    } else if (cp < 0x800) {
      out.push_back(static_cast<char>(0xC0 | (cp >> 6)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else if (cp < 0x10000) {
      out.push_back(static_cast<char>(0xE0 | (cp >> 12)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else {
      out.push_back(static_cast<char>(0xF0 | (cp >> 18)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    }
  }
  static std::string hex2(unsigned c) {
    char b[8];
    std::snprintf(b, sizeof b, "%02x", c);
    return b;
  }
  static std::string hex_of(unsigned c) {
    char b[8];
    std::snprintf(b, sizeof b, "%04x", c);
    return b;
  }
  bool digit() {
    if (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9') {
      ++i_;
      return true;
    }
    return false;
  }
  bool literal(const char* word) {
    const std::size_t n = std::strlen(word);
    if (s_.compare(i_, n, word) != 0) return false;
    i_ += n;
    return true;
  }
  void ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\r' || s_[i_] == '\n')) ++i_;
  }
  bool eat(char c) {
    if (i_ < s_.size() && s_[i_] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  [[nodiscard]] char peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }
  [[nodiscard]] bool at_end() const { return i_ >= s_.size(); }
  bool fail(const std::string& what) { return fail(what, i_); }
  bool fail(const std::string& what, std::size_t at) {
    error_ = "column " + std::to_string(at + 1) + ": " + what;
    return false;
  }

  const std::string& s_;
  std::size_t i_ = 0;
  std::string error_;
};

void escape_into(std::string& out, const std::string& s) {
  out.push_back('"');
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      case '\b': out += "\\b"; break;
      case '\f': out += "\\f"; break;
      default:
        if (c < 0x20 || c == 0x7f) {
          char b[8];
          std::snprintf(b, sizeof b, "\\u%04x", c);
          out += b;
        } else {
          out.push_back(ch);  // UTF-8 passes through
        }
    }
  }
  out.push_back('"');
}

/// Exact unsigned 64-bit id (lode::Json keeps 10 digits, which is why it is not used here).
bool parse_id(const Scalar& v, std::uint64_t& id, std::string& error) {
  const auto bad = [&](const std::string& why) {
    error = "column " + std::to_string(v.column) + ": \"id\" " + why;
    return false;
  };
  if (v.kind != Scalar::Kind::number) return bad("must be a number");
  if (v.text.find_first_not_of("0123456789") != std::string::npos)
    return bad("must be a non-negative integer without fraction or exponent, got " + v.text);
  std::uint64_t x = 0;
  for (const char c : v.text) {
    const auto d = static_cast<std::uint64_t>(c - '0');
    if (x > (std::numeric_limits<std::uint64_t>::max() - d) / 10) return bad("does not fit in 64 bits: " + v.text);
    x = x * 10 + d;
  }
  id = x;
  return true;
}

bool check_duplicates(const std::vector<Member>& members, std::string& error) {
  for (std::size_t a = 0; a < members.size(); ++a)
    for (std::size_t b = 0; b < a; ++b)
      if (members[a].key == members[b].key) {
        error = "column " + std::to_string(members[a].column) + ": duplicate key \"" + members[a].key + "\"";
        return false;
      }
  return true;
}

bool valid_pipeline_name(const std::string& name) {
  if (name.empty() || name.size() > 64 || name[0] == '.' || name[0] == '-') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
  });
}

bool fill_address(const std::string& path, sockaddr_un& addr, std::string& error) {
  std::memset(&addr, 0, sizeof addr);
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path) {
    error = "socket path " + path + " is " + std::to_string(path.size()) + " bytes, longer than the " +
            std::to_string(sizeof addr.sun_path - 1) + " a Unix socket allows (use a shorter XDG_RUNTIME_DIR)";
    return false;
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return true;
}

/// The directory exists (created 0700 if not, parents too: a test may point XDG_RUNTIME_DIR
/// at a fresh path), is a real directory, ours, and private.
Status ensure_private_dir(const std::string& dir) {
  const auto make = [](const std::string& d) { return ::mkdir(d.c_str(), 0700) == 0 ? 0 : errno; };
  int e = make(dir);
  if (e == ENOENT) {
    for (std::size_t at = dir.find('/', 1); at != std::string::npos; at = dir.find('/', at + 1))
      make(dir.substr(0, at));  // a failure shows in the retry below
    e = make(dir);
  }
  if (e != 0 && e != EEXIST)
    return Status::error("cannot create " + dir + ": " + errno_text(e) +
                         (std::getenv("XDG_RUNTIME_DIR") ? " (check XDG_RUNTIME_DIR)" : ""));
  struct stat st {};
  if (::lstat(dir.c_str(), &st) != 0) return Status::error("cannot stat " + dir + ": " + errno_text(errno));
  if (!S_ISDIR(st.st_mode)) return Status::error(dir + " exists and is not a directory (a symlink?); not using it for the command socket");
  if (st.st_uid != ::geteuid())
    return Status::error(dir + " belongs to uid " + std::to_string(st.st_uid) + ", not to you (uid " +
                         std::to_string(::geteuid()) + "): refusing to put the command socket there (set XDG_RUNTIME_DIR)");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return Status::error(dir + " has mode " + mode + ": other users could reach the command socket; run `chmod 700 " +
                         dir + "` (only the owner may command a pipeline)");
  }
  return {};
}

/// SO_PEERCRED of a connected Unix socket.
std::optional<ucred> peer_of(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return std::nullopt;
  return cred;
}

/// Nonblocking connect; 0 = connected, else errno. EAGAIN: the backlog is full (it lives).
int connect_unix(const std::string& path, int& fd) {
  sockaddr_un addr{};
  std::string error;
  if (!fill_address(path, addr, error)) return ENAMETOOLONG;
  fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return errno;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) return 0;
  const int e = errno;
  ::close(fd);
  fd = -1;
  return e;
}

std::string pid_text(pid_t pid) { return pid > 0 ? "pid " + std::to_string(pid) : "pid unknown"; }

}  // namespace

// ---------------------------------------------------------------------------------------
std::string local_control_dir() {
  const char* xdg = std::getenv("XDG_RUNTIME_DIR");
  if (xdg && *xdg) return std::string(xdg) + "/lode";
  return "/tmp/lode-" + std::to_string(::geteuid());
}

std::string local_control_socket(const std::string& pipeline) { return local_control_dir() + "/" + pipeline + ".sock"; }

std::optional<pid_t> probe_local_socket(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISSOCK(st.st_mode)) return std::nullopt;
  int fd = -1;
  const int e = connect_unix(path, fd);
  if (e == EAGAIN) return pid_t{0};  // listening, backlog full
  if (e != 0) return std::nullopt;   // ECONNREFUSED: stale
  const auto cred = peer_of(fd);
  ::close(fd);
  return cred ? cred->pid : pid_t{0};
}

std::vector<LocalPipeline> live_local_pipelines() {
  std::vector<LocalPipeline> out;
  const std::string dir = local_control_dir();
  DIR* d = ::opendir(dir.c_str());
  if (!d) return out;
  while (const dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() <= 5 || name.compare(name.size() - 5, 5, ".sock") != 0) continue;
    LocalPipeline p;
    p.pipeline = name.substr(0, name.size() - 5);
    p.path = dir + "/" + name;
    if (auto pid = probe_local_socket(p.path)) {
      p.pid = *pid;
      out.push_back(std::move(p));
    }
  }
  ::closedir(d);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.pipeline < b.pipeline; });
  return out;
}

// ---------------------------------------------------------------------------------------
std::string encode_request(const ControlRequest& r) {
  std::string out = "{\"id\": " + std::to_string(r.id) + ", \"kind\": ";
  escape_into(out, r.kind);
  const std::pair<const char*, const std::string*> fields[] = {
      {"block", &r.block}, {"name", &r.name}, {"value", &r.value}, {"plugin", &r.plugin}, {"client", &r.client}};
  for (const auto& [key, text] : fields) {
    if (text->empty()) continue;
    out += ", \"";
    out += key;
    out += "\": ";
    escape_into(out, *text);
  }
  out += "}";
  return out;
}

std::string encode_reply(const ControlReply& r) {
  std::string out = "{\"id\": " + std::to_string(r.id) + ", \"ok\": " + (r.ok ? "true" : "false") + ", \"message\": ";
  escape_into(out, r.message);
  out += ", \"value\": ";
  escape_into(out, r.value);
  out += "}";
  return out;
}

Expected<ControlRequest> decode_request(const std::string& line, std::uint64_t* id_seen) {
  std::vector<Member> members;
  FlatParser parser(line);
  const bool parsed = parser.parse(members);
  // The id, when it was read, goes back even with a syntax error later in the line, so the
  // client can match the refusal to its request.
  std::string error;
  ControlRequest r;
  bool has_id = false;
  for (const auto& m : members)
    if (m.key == "id" && !has_id && parse_id(m.value, r.id, error)) {
      has_id = true;
      if (id_seen) *id_seen = r.id;
    }
  if (!parsed) return Status::error(parser.error());
  if (!check_duplicates(members, error)) return Status::error(error);
  bool has_kind = false;
  for (const auto& m : members) {
    const auto need_string = [&](std::string& into) {
      if (m.value.kind != Scalar::Kind::string) {
        error = "column " + std::to_string(m.value.column) + ": \"" + m.key + "\" must be a string";
        return false;
      }
      into = m.value.text;
      return true;
    };
    if (m.key == "id") {
      if (!parse_id(m.value, r.id, error)) return Status::error(error);
    } else if (m.key == "kind") {
      if (!need_string(r.kind)) return Status::error(error);
      has_kind = true;
    } else if (m.key == "block") {
      if (!need_string(r.block)) return Status::error(error);
    } else if (m.key == "name") {
      if (!need_string(r.name)) return Status::error(error);
    } else if (m.key == "plugin") {
      if (!need_string(r.plugin)) return Status::error(error);
    } else if (m.key == "client") {
      if (!need_string(r.client)) return Status::error(error);
    } else if (m.key == "value") {
      r.value = m.value.text;  // a string, a number as written, or true/false: the service parses it
    } else {
      return Status::error("column " + std::to_string(m.column) + ": unknown key \"" + m.key +
                           "\" (a request has id, kind, block, name, value, plugin, client)");
    }
  }
  if (!has_kind)
    return Status::error("missing \"kind\" (set, get, list, swap, promote, record_start, record_stop, status)");
  if (r.kind.empty()) return Status::error("\"kind\" is empty (set, get, list, swap, promote, record_start, record_stop, status)");
  return r;
}

Expected<ControlReply> decode_reply(const std::string& line) {
  std::vector<Member> members;
  FlatParser parser(line);
  if (!parser.parse(members)) return Status::error("malformed reply: " + parser.error());
  std::string error;
  if (!check_duplicates(members, error)) return Status::error("malformed reply: " + error);
  ControlReply r;
  bool has_ok = false;
  for (const auto& m : members) {
    const auto wrong = [&](const char* what) {
      return Status::error("malformed reply: column " + std::to_string(m.value.column) + ": \"" + m.key + "\" must be " + what);
    };
    if (m.key == "id") {
      if (!parse_id(m.value, r.id, error)) return Status::error("malformed reply: " + error);
    } else if (m.key == "ok") {
      if (m.value.kind != Scalar::Kind::boolean) return wrong("true or false");
      r.ok = m.value.text == "true";
      has_ok = true;
    } else if (m.key == "message") {
      if (m.value.kind != Scalar::Kind::string) return wrong("a string");
      r.message = m.value.text;
    } else if (m.key == "value") {
      if (m.value.kind != Scalar::Kind::string) return wrong("a string");
      r.value = m.value.text;
    } else {
      return Status::error("malformed reply: unknown key \"" + m.key + "\"");
    }
  }
  if (!has_ok) return Status::error("malformed reply: no \"ok\"");
  return r;
}

// ---------------------------------------------------------------------------------------
LocalControlServer::LocalControlServer(ControlService& service, LocalControlOptions options)
    : service_(service), options_(std::move(options)) {}

Expected<std::unique_ptr<LocalControlServer>> LocalControlServer::start(ControlService& service,
                                                                        const std::string& pipeline,
                                                                        const LocalControlOptions& options) {
  if (!valid_pipeline_name(pipeline))
    return Status::error("local control: pipeline name '" + pipeline +
                         "' cannot name a socket file (1-64 letters, digits, '_', '-', '.'; not starting with '.' or '-')");
  std::unique_ptr<LocalControlServer> s(new LocalControlServer(service, options));
  s->pipeline_ = pipeline;
  const std::string dir = options.dir.empty() ? local_control_dir() : options.dir;
  if (auto st = ensure_private_dir(dir); !st) return Status::error("local control: " + st.message());
  s->path_ = dir + "/" + pipeline + ".sock";
  sockaddr_un addr{};
  std::string error;
  if (!fill_address(s->path_, addr, error)) return Status::error("local control: " + error);

  // One run per pipeline and user: the lock decides (the kernel drops it when a run dies,
  // so a crash never blocks the next run); the pid inside is for the message.
  const std::string lock_path = dir + "/" + pipeline + ".lock";
  s->lock_fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (s->lock_fd_ < 0) return Status::error("local control: cannot open " + lock_path + ": " + errno_text(errno));
  if (::flock(s->lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    pid_t pid = probe_local_socket(s->path_).value_or(0);
    if (pid == 0) {
      char buf[32] = {};
      if (::pread(s->lock_fd_, buf, sizeof buf - 1, 0) > 0) pid = static_cast<pid_t>(std::atol(buf));
    }
    return Status::error("pipeline " + pipeline + " is already running locally (" + pid_text(pid) + ", socket " +
                         s->path_ + "); stop it first, or start this one with --no-local-control");
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(s->lock_fd_, 0) != 0 || ::pwrite(s->lock_fd_, pid.data(), pid.size(), 0) < 0) {
    // The pid is only for messages; the lock itself holds.
  }

  struct stat st {};
  if (::lstat(s->path_.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode))
      return Status::error("local control: " + s->path_ + " exists and is not a socket; not touching it (remove it by hand)");
    if (auto live = probe_local_socket(s->path_))
      return Status::error("pipeline " + pipeline + " is already running locally (" + pid_text(*live) + ", socket " +
                           s->path_ + "); stop it first, or start this one with --no-local-control");
    if (::unlink(s->path_.c_str()) != 0 && errno != ENOENT)
      return Status::error("local control: cannot remove the stale socket " + s->path_ + ": " + errno_text(errno));
    s->replaced_stale_ = true;
  }

  s->listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (s->listen_fd_ < 0) return Status::error("local control: socket(): " + errno_text(errno));
  if (::bind(s->listen_fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
    return Status::error("local control: cannot bind " + s->path_ + ": " + errno_text(errno));
  // The 0700 directory already keeps other users out between bind() and chmod().
  if (::chmod(s->path_.c_str(), 0600) != 0 || ::lstat(s->path_.c_str(), &st) != 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: cannot chmod 0600 " + s->path_ + ": " + errno_text(e));
  }
  s->dev_ = st.st_dev;
  s->ino_ = st.st_ino;
  if (::listen(s->listen_fd_, 16) != 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: listen on " + s->path_ + ": " + errno_text(e));
  }
  s->stop_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (s->stop_fd_ < 0) {
    const int e = errno;
    ::unlink(s->path_.c_str());
    return Status::error("local control: eventfd: " + errno_text(e));
  }
  LocalControlServer* raw = s.get();
  s->thread_ = std::thread([raw] { raw->serve(); });
  return s;
}

LocalControlServer::~LocalControlServer() { stop(); }

void LocalControlServer::stop() {
  if (thread_.joinable()) {
    const std::uint64_t one = 1;
    if (::write(stop_fd_, &one, sizeof one) < 0) {
      // An eventfd write only fails when the counter would overflow: it is already set.
    }
    thread_.join();
  }
  if (listen_fd_ >= 0) {
    // Remove the file only if it is still the one we bound (never another run's).
    struct stat st {};
    if (::lstat(path_.c_str(), &st) == 0 && st.st_dev == dev_ && st.st_ino == ino_) ::unlink(path_.c_str());
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  if (stop_fd_ >= 0) {
    ::close(stop_fd_);
    stop_fd_ = -1;
  }
  if (lock_fd_ >= 0) {
    ::close(lock_fd_);  // releases the flock; the lock file stays (unlinking it would race)
    lock_fd_ = -1;
  }
}

LocalControlStats LocalControlServer::stats() const {
  LocalControlStats s;
  s.connections = connections_.load();
  s.requests = requests_.load();
  s.malformed = malformed_.load();
  s.refused_clients = refused_.load();
  return s;
}

void LocalControlServer::serve() {
  struct Conn {
    int fd = -1;
    std::string who;  ///< "local pid N uid U"
    std::string in, out;
    bool closing = false;  ///< no more input: close once `out` is sent
  };
  std::vector<Conn> conns;
  std::vector<pollfd> fds;
  constexpr std::size_t kMaxPending = 1 << 20;  // reply bytes queued: stop reading above this

  const auto reply_line = [](const ControlReply& r) { return encode_reply(r) + "\n"; };
  const auto handle_line = [&](Conn& c, std::string line) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) return;  // blank lines (nc, telnet) are ignored
    std::uint64_t id = 0;
    auto request = decode_request(line, &id);
    ControlReply reply;
    if (!request) {
      malformed_.fetch_add(1);
      reply.id = id;
      reply.message = "malformed request: " + request.error();
    } else {
      requests_.fetch_add(1);
      request->client = request->client.empty() ? c.who : request->client + " via " + c.who;
      try {
        reply = service_.handle(*request, options_.handle_timeout);
      } catch (const std::exception& ex) {
        reply = ControlReply{};
        reply.message = request->kind + ": internal error: " + ex.what();
      }
      reply.id = request->id;
    }
    c.out += reply_line(reply);
  };

  for (;;) {
    fds.clear();
    fds.push_back({stop_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (const auto& c : conns) {
      short ev = 0;
      if (!c.closing && c.out.size() < kMaxPending) ev |= POLLIN;
      if (!c.out.empty()) ev |= POLLOUT;
      fds.push_back({c.fd, ev, 0});
    }
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      break;  // cannot happen with valid fds; leaving ends the service, stop() still cleans up
    }
    if (fds[0].revents) break;
    const std::size_t polled = conns.size();  // conns accepted below are polled next round

    for (std::size_t k = 0; k < polled; ++k) {
      Conn& c = conns[k];
      const short re = fds[k + 2].revents;
      if (re & (POLLIN | POLLHUP | POLLERR)) {
        char buf[4096];
        const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
        if (n > 0) {
          c.in.append(buf, static_cast<std::size_t>(n));
        } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
          // End of input: a last line without '\n' (e.g. after shutdown(SHUT_WR)) still counts.
          if (n == 0 && !c.in.empty()) {
            handle_line(c, std::move(c.in));
            c.in.clear();
          }
          c.closing = true;
          if (n < 0) c.out.clear();  // the peer is gone
        }
        std::size_t nl;
        while (!c.in.empty() && (nl = c.in.find('\n')) != std::string::npos) {
          std::string line = c.in.substr(0, nl);
          c.in.erase(0, nl + 1);
          handle_line(c, std::move(line));
        }
        if (c.in.size() > options_.max_line) {
          refused_.fetch_add(1);
          ControlReply r;
          r.message = "malformed request: a request line longer than " + std::to_string(options_.max_line) +
                      " bytes without a newline; closing the connection";
          c.out += reply_line(r);
          c.in.clear();
          c.closing = true;
        }
      }
      if (!c.out.empty()) {  // replies go out at once; what does not fit waits for POLLOUT
        const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0) c.out.erase(0, static_cast<std::size_t>(n));
        else if (n < 0 && errno != EAGAIN && errno != EINTR) c.out.clear(), c.closing = true;
      }
    }
    // Drop finished clients.
    for (std::size_t k = conns.size(); k-- > 0;) {
      if (conns[k].closing && conns[k].out.empty()) {
        ::close(conns[k].fd);
        conns.erase(conns.begin() + static_cast<std::ptrdiff_t>(k));
      }
    }
    if (fds[1].revents & POLLIN) {
      for (;;) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (fd < 0) break;  // EAGAIN: all taken
        connections_.fetch_add(1);
        if (conns.size() >= options_.max_clients) {
          refused_.fetch_add(1);
          ControlReply r;
          r.message = "too many local clients (" + std::to_string(options_.max_clients) + " connected); retry";
          const std::string line = reply_line(r);
          (void)::send(fd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
          ::close(fd);
          continue;
        }
        Conn c;
        c.fd = fd;
        const auto cred = peer_of(fd);
        c.who = cred ? "local pid " + std::to_string(cred->pid) + " uid " + std::to_string(cred->uid) : "local client";
        conns.push_back(std::move(c));
      }
    }
  }
  for (auto& c : conns) ::close(c.fd);
}

// ---------------------------------------------------------------------------------------
Expected<ControlReply> local_send(const std::string& path, const ControlRequest& request,
                                  std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  const auto remaining_ms = [&]() -> int {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    return left <= 0 ? 0 : static_cast<int>(std::min<long long>(left, 1 << 30));
  };
  int fd = -1;
  for (;;) {
    const int e = connect_unix(path, fd);
    if (e == 0) break;
    if (e == EAGAIN && remaining_ms() > 0) {  // backlog full: the server is busy, not gone
      ::usleep(2000);
      continue;
    }
    switch (e) {
      case ENOENT:
        return Status::error("no local pipeline at " + path + " (is `lode run` running on this host, as this user, without --no-local-control?)");
      case ECONNREFUSED:
        return Status::error(path + " is stale: nothing listens there (left by a run that crashed; the next `lode run` of that pipeline replaces it)");
      case EACCES:
      case EPERM:
        return Status::error("permission denied on " + path + ": only the user who started the run may command it");
      case EAGAIN:
        return Status::error("the pipeline at " + path + " accepted no connection within " +
                             std::to_string(timeout.count()) + " ms (its command queue is full)");
      default:
        return Status::error("cannot connect to " + path + ": " + errno_text(e));
    }
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  // The file system already limits who can connect; this checks the other direction: the
  // socket we talk to is served by ourselves (or root), not by someone who planted it.
  if (const auto cred = peer_of(fd); cred && cred->uid != ::geteuid() && cred->uid != 0)
    return Status::error(path + " is served by uid " + std::to_string(cred->uid) + ", not by you (uid " +
                         std::to_string(::geteuid()) + "): not sending the command");

  const std::string line = encode_request(request) + "\n";
  std::size_t sent = 0;
  while (sent < line.size()) {
    const ssize_t n = ::send(fd, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      pollfd p{fd, POLLOUT, 0};
      if (::poll(&p, 1, remaining_ms()) == 0)
        return Status::error("could not send the request to " + path + " within " + std::to_string(timeout.count()) + " ms");
      continue;
    }
    return Status::error("sending to " + path + ": " + errno_text(errno));
  }
  std::string in;
  for (;;) {
    const auto nl = in.find('\n');
    if (nl != std::string::npos) {
      auto reply = decode_reply(in.substr(0, nl));
      if (!reply) return Status::error(path + ": " + reply.error());
      if (reply->id != request.id && reply->id != 0)
        return Status::error(path + ": reply to request " + std::to_string(reply->id) + ", expected " +
                             std::to_string(request.id));
      return reply;
    }
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, remaining_ms());
    if (ready == 0)
      return Status::error("no reply from " + path + " within " + std::to_string(timeout.count()) +
                           " ms (a swap may take longer: raise --timeout)");
    if (ready < 0 && errno == EINTR) continue;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n > 0) in.append(buf, static_cast<std::size_t>(n));
    else if (n == 0) return Status::error("the pipeline at " + path + " closed the connection without replying (did it stop?)");
    else if (errno != EAGAIN && errno != EINTR) return Status::error("reading from " + path + ": " + errno_text(errno));
  }
}

}  // namespace lode::cli
