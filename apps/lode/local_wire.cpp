#include "local_wire.hpp"

#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

namespace lode::cli {

namespace {

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

}  // namespace

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

}  // namespace lode::cli
