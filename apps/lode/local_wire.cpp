#include "local_wire.hpp"

#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include <nlohmann/json.hpp>

namespace lode::cli {

namespace {

// One flat JSON object, read with nlohmann-json's SAX parser (RFC 8259 syntax, UTF-8 and
// surrogate pairs, its error positions), so that this file only says what a request may be:
// an object of strings, numbers and booleans, numbers kept as written (the service parses
// them, and an id must stay exact to 64 bits).
struct Scalar {
  enum class Kind { string, number, boolean } kind = Kind::string;
  std::string text;  ///< string: decoded; number: as written (integers in decimal); boolean: "true"/"false"
};
struct Member {
  std::string key;
  Scalar value;
};

class FlatObjectReader final : public nlohmann::json_sax<nlohmann::json> {
 public:
  bool null() override { return refuse("null is not accepted"); }
  bool boolean(bool value) override { return scalar(Scalar::Kind::boolean, value ? "true" : "false"); }
  bool number_integer(number_integer_t value) override { return scalar(Scalar::Kind::number, std::to_string(value)); }
  bool number_unsigned(number_unsigned_t value) override {
    return scalar(Scalar::Kind::number, std::to_string(value));
  }
  bool number_float(number_float_t, const string_t& as_written) override {
    return scalar(Scalar::Kind::number, as_written);
  }
  bool string(string_t& value) override { return scalar(Scalar::Kind::string, value); }
  bool binary(binary_t&) override { return refuse("binary values are not accepted"); }
  bool start_object(std::size_t) override {
    return depth_++ == 0 ? true : refuse(kNested);
  }
  bool end_object() override {
    --depth_;
    return true;
  }
  bool start_array(std::size_t) override { return refuse(kNested); }
  bool end_array() override { return true; }
  bool key(string_t& name) override {
    members_.push_back({name, {}});
    return true;
  }
  bool parse_error(std::size_t position, const std::string&, const nlohmann::detail::exception& ex) override {
    // "[json.exception.parse_error.101] parse error at line 1, column 16: syntax error ..."
    std::string what = ex.what();
    if (const auto colon = what.find(": "); colon != std::string::npos && what.find("column") < colon)
      what = what.substr(colon + 2);
    error_ = "column " + std::to_string(position) + ": " + what;
    return false;
  }

  [[nodiscard]] const std::vector<Member>& members() const { return members_; }
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  static constexpr const char* kNested =
      "nested objects and arrays are not accepted (a flat object of strings, numbers and booleans)";
  bool scalar(Scalar::Kind kind, std::string text) {
    if (depth_ != 1 || members_.empty()) return refuse("expected '{' (a request is one JSON object per line)");
    members_.back().value = {kind, std::move(text)};
    return true;
  }
  bool refuse(const std::string& why) {
    error_ = members_.empty() ? why : "\"" + members_.back().key + "\": " + why;
    return false;
  }

  int depth_ = 0;
  std::vector<Member> members_;
  std::string error_;
};

/// Parses `line` into `out`; false with `error` set when it is not one flat object.
bool parse_flat_object(const std::string& line, std::vector<Member>& out, std::string& error) {
  const auto first = line.find_first_not_of(" \t\r");
  if (first == std::string::npos) {
    error = "empty request (expected a JSON object)";
    return false;
  }
  if (line[first] != '{') {
    error = "column " + std::to_string(first + 1) + ": expected '{' (a request is one JSON object per line)";
    return false;
  }
  FlatObjectReader reader;
  const bool ok = nlohmann::json::sax_parse(line, &reader, nlohmann::json::input_format_t::json, true);
  out = reader.members();
  if (!ok) error = reader.error();
  return ok;
}

/// A JSON string; bytes that are not UTF-8 become U+FFFD rather than an exception.
void escape_into(std::string& out, const std::string& text) {
  out += nlohmann::json(text).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

/// Exact unsigned 64-bit id (lode::Json keeps 10 digits, which is why it is not used here).
bool parse_id(const Scalar& v, std::uint64_t& id, std::string& error) {
  const auto bad = [&](const std::string& why) {
    error = "\"id\" " + why;
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
        error = "duplicate key \"" + members[a].key + "\"";
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
  std::string parse_error;
  const bool parsed = parse_flat_object(line, members, parse_error);
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
  if (!parsed) return Status::error(parse_error);
  if (!check_duplicates(members, error)) return Status::error(error);
  bool has_kind = false;
  for (const auto& m : members) {
    const auto need_string = [&](std::string& into) {
      if (m.value.kind != Scalar::Kind::string) {
        error = "\"" + m.key + "\" must be a string";
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
      return Status::error("unknown key \"" + m.key +
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
  std::string parse_error;
  if (!parse_flat_object(line, members, parse_error)) return Status::error("malformed reply: " + parse_error);
  std::string error;
  if (!check_duplicates(members, error)) return Status::error("malformed reply: " + error);
  ControlReply r;
  bool has_ok = false;
  for (const auto& m : members) {
    const auto wrong = [&](const char* what) {
      return Status::error("malformed reply: \"" + m.key + "\" must be " + what);
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
