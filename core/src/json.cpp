#include "lode/sdk/json.hpp"

#include <cmath>
#include <cstdio>

namespace lode {

Json::Json(const std::vector<double>& v) : type_(Type::array) {
  array_.reserve(v.size());
  for (double d : v) array_.emplace_back(d);
}

Json& Json::operator[](const std::string& key) {
  if (type_ == Type::null) type_ = Type::object;
  for (auto& [k, v] : object_)
    if (k == key) return v;
  object_.emplace_back(key, Json());
  return object_.back().second;
}

Json& Json::push(Json value) {
  if (type_ == Type::null) type_ = Type::array;
  array_.push_back(std::move(value));
  return array_.back();
}

const Json* Json::find(const std::string& key) const {
  for (const auto& [k, v] : object_)
    if (k == key) return &v;
  return nullptr;
}

std::string Json::dump(int indent) const {
  std::string out;
  dump_to(out, indent, 0);
  return out;
}

namespace {
void escape_to(std::string& out, const std::string& s) {
  out.push_back('"');
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out.push_back(c);
        }
    }
  }
  out.push_back('"');
}
void newline(std::string& out, int indent, int depth) {
  if (indent < 0) return;
  out.push_back('\n');
  out.append(static_cast<std::size_t>(indent * depth), ' ');
}
}  // namespace

void Json::dump_to(std::string& out, int indent, int depth) const {
  switch (type_) {
    case Type::null: out += "null"; break;
    case Type::boolean: out += bool_ ? "true" : "false"; break;
    case Type::number: {
      if (!std::isfinite(number_)) { out += "null"; break; }
      char buf[40];
      std::snprintf(buf, sizeof buf, "%.10g", number_);
      out += buf;
      break;
    }
    case Type::string: escape_to(out, string_); break;
    case Type::array: {
      // Arrays of numbers stay on one line: coefficient vectors read better that way.
      bool flat = true;
      for (const auto& e : array_) flat = flat && (e.type_ != Type::array && e.type_ != Type::object);
      out.push_back('[');
      for (std::size_t i = 0; i < array_.size(); ++i) {
        if (i) out += flat || indent < 0 ? ", " : ",";
        if (!flat) newline(out, indent, depth + 1);
        array_[i].dump_to(out, indent, depth + 1);
      }
      if (!flat && !array_.empty()) newline(out, indent, depth);
      out.push_back(']');
      break;
    }
    case Type::object: {
      out.push_back('{');
      for (std::size_t i = 0; i < object_.size(); ++i) {
        if (i) out += indent < 0 ? ", " : ",";
        newline(out, indent, depth + 1);
        escape_to(out, object_[i].first);
        out += ": ";
        object_[i].second.dump_to(out, indent, depth + 1);
      }
      if (!object_.empty()) newline(out, indent, depth);
      out.push_back('}');
      break;
    }
  }
}

}  // namespace lode
