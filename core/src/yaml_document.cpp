#include "yaml_document.hpp"

#include <utf8.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <string_view>

#include "params_node.hpp"

namespace lode::detail {

namespace {

/// One bounded walk over the parsed graph. Stops at the first depth or expansion problem
/// (the rest of the document may be the same cycle or bomb), but collects every key problem.
class DocumentCheck {
 public:
  DocumentCheck(const std::string& file, Diagnostics& diagnostics, int max_depth, std::size_t max_nodes)
      : file_(file), diag_(diagnostics), max_depth_(max_depth), max_nodes_(max_nodes) {}

  /// False once the walk was cut short (too deep or too many nodes).
  bool walk(const YAML::Node& n, const std::string& path, int depth) {
    if (++nodes_ > max_nodes_) {
      diag_.add(location_of(n, file_), path,
                "the document expands to more than " + std::to_string(max_nodes_) +
                    " nodes (aliases are counted at each use): refused, as an alias bomb would be");
      return false;
    }
    if (!n.IsMap() && !n.IsSequence()) return true;
    if (depth >= max_depth_) {
      diag_.add(location_of(n, file_), path,
                "nested deeper than " + std::to_string(max_depth_) +
                    " levels: refused (a recursive alias such as `a: &r [1, *r]` nests forever)");
      return false;
    }
    if (n.IsSequence()) {
      std::size_t i = 0;
      for (const auto& e : n) {
        // A scalar needs no path unless it is the one over budget: long number lists stay cheap.
        const bool leaf = !e.IsMap() && !e.IsSequence();
        if (leaf && nodes_ + 1 <= max_nodes_) {
          ++nodes_;
        } else if (!walk(e, path + "[" + std::to_string(i) + "]", depth + 1)) {
          return false;
        }
        ++i;
      }
      return true;
    }
    std::set<std::string> seen;
    for (const auto& kv : n) {
      if (!kv.first.IsScalar()) {
        // Count the key too: a bomb may hide in keys.
        nodes_ += 1;
        diag_.add(location_of(kv.first, file_), path,
                  "a key must be a plain scalar (a name), not a " +
                      std::string(kv.first.IsMap() ? "map" : kv.first.IsSequence() ? "list" : "null"));
        continue;
      }
      const std::string& key = kv.first.Scalar();
      const std::string child = path.empty() ? key : path + "." + key;
      if (!seen.insert(key).second)
        diag_.add(location_of(kv.first, file_), child,
                  "duplicate key '" + key + "' (the earlier value would be silently ignored)");
      if (!walk(kv.second, child, depth + 1)) return false;
    }
    return true;
  }

 private:
  const std::string& file_;
  Diagnostics& diag_;
  int max_depth_;
  std::size_t max_nodes_;
  std::size_t nodes_ = 0;
};

}  // namespace

namespace {

/// The first byte of `text` that is not UTF-8, located: yaml-cpp passes such bytes on into
/// names, units and strings (and from there into JSON and DDS), and a file saved as Latin-1
/// or Windows-1252 ("µm" as 0xB5) is the usual cause. A text that starts with a UTF-16 or
/// UTF-32 byte order mark is left to yaml-cpp, which reads those encodings.
bool check_utf8(const std::string& text, const std::string& label, Diagnostics& diagnostics) {
  const auto starts_with = [&](std::string_view mark) { return std::string_view(text).substr(0, mark.size()) == mark; };
  using namespace std::string_view_literals;
  if (starts_with("\xFE\xFF"sv) || starts_with("\xFF\xFE"sv) || starts_with("\x00\x00\xFE\xFF"sv)) return true;
  const auto bad = utf8::find_invalid(text.begin(), text.end());
  if (bad == text.end()) return true;
  const std::size_t at = static_cast<std::size_t>(bad - text.begin());
  const std::size_t line_start = text.rfind('\n', at == 0 ? 0 : at - 1);
  const std::size_t from = (line_start == std::string::npos || at == 0) ? 0 : line_start + 1;
  const int line = 1 + static_cast<int>(std::count(text.begin(), bad, '\n'));
  const int column = 1 + static_cast<int>(utf8::distance(text.begin() + static_cast<std::ptrdiff_t>(from), bad));
  char byte[8];
  std::snprintf(byte, sizeof byte, "0x%02X", static_cast<unsigned>(static_cast<unsigned char>(*bad)));
  diagnostics.add({label, line, column}, "",
                  std::string("not UTF-8 text: byte ") + byte +
                      " (a configuration is UTF-8; save it as UTF-8, e.g. iconv -f latin1 -t utf-8, or see "
                      "whether the file was damaged)");
  return false;
}

}  // namespace

std::optional<YAML::Node> parse_config_yaml(const std::string& text, const std::string& label,
                                            Diagnostics& diagnostics, int max_depth, std::size_t max_nodes) {
  if (!check_utf8(text, label, diagnostics)) return std::nullopt;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& ex) {
    // ParserException (syntax), DeepRecursion (nesting past yaml-cpp's own limit) and any
    // other yaml-cpp error: all located where the parser stopped.
    const int line = ex.mark.line >= 0 ? ex.mark.line + 1 : 0;
    const int column = ex.mark.column >= 0 ? ex.mark.column + 1 : 0;
    diagnostics.add({label, line, column}, "", "YAML syntax error: " + ex.msg);
    return std::nullopt;
  }
  const std::size_t before = diagnostics.size();
  DocumentCheck check(label, diagnostics, max_depth, max_nodes);
  check.walk(root, "", 0);
  if (diagnostics.size() != before) return std::nullopt;
  return root;
}

}  // namespace lode::detail
