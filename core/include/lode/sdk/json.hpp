// A small ordered JSON value for `lode describe`, summaries and plugin listings.
//
// Off the RT path only. Keys keep insertion order so output reads like the YAML it came from.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace lode {

class Json {
 public:
  enum class Type { null, boolean, number, string, array, object };

  Json() = default;
  Json(std::nullptr_t) {}                                          // NOLINT
  Json(bool b) : type_(Type::boolean), bool_(b) {}                 // NOLINT
  Json(double d) : type_(Type::number), number_(d) {}              // NOLINT
  Json(int i) : type_(Type::number), number_(i) {}                 // NOLINT
  Json(std::int64_t i) : type_(Type::number), number_(static_cast<double>(i)) {}  // NOLINT
  Json(std::uint64_t i) : type_(Type::number), number_(static_cast<double>(i)) {}  // NOLINT
  Json(std::size_t i, int /*tag*/) = delete;
  Json(const char* s) : type_(Type::string), string_(s) {}         // NOLINT
  Json(std::string s) : type_(Type::string), string_(std::move(s)) {}  // NOLINT
  Json(const std::vector<double>& v);                              // NOLINT

  static Json object() { Json j; j.type_ = Type::object; return j; }
  static Json array() { Json j; j.type_ = Type::array; return j; }

  /// Object access; converts a null into an object. Insertion order is kept.
  Json& operator[](const std::string& key);
  /// Appends to an array; converts a null into an array.
  Json& push(Json value);

  [[nodiscard]] Type type() const { return type_; }
  [[nodiscard]] double as_number() const { return number_; }
  [[nodiscard]] const std::string& as_string() const { return string_; }
  [[nodiscard]] bool as_bool() const { return bool_; }
  [[nodiscard]] const std::vector<Json>& elements() const { return array_; }
  [[nodiscard]] const std::vector<std::pair<std::string, Json>>& members() const { return object_; }
  [[nodiscard]] const Json* find(const std::string& key) const;

  /// indent < 0: one line. Numbers keep 10 significant digits.
  [[nodiscard]] std::string dump(int indent = 2) const;

 private:
  void dump_to(std::string& out, int indent, int depth) const;
  Type type_ = Type::null;
  bool bool_ = false;
  double number_ = 0.0;
  std::string string_;
  std::vector<Json> array_;
  std::vector<std::pair<std::string, Json>> object_;
};

}  // namespace lode
