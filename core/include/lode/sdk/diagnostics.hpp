// Configuration problems with their place in the YAML file.
//
// Loading a pipeline collects every problem it can find (not only the first) and refuses to
// start if there is any; each one names file:line:column and the dotted field path.
#pragma once

#include <string>
#include <vector>

namespace lode {

struct SourceLocation {
  std::string file;
  int line = 0;    ///< 1-based; 0 when unknown
  int column = 0;  ///< 1-based; 0 when unknown
};

struct Diagnostic {
  SourceLocation where;
  std::string field;  ///< dotted path, e.g. "blocks.glsdc.iterations"
  std::string message;

  /// "file:line:column: field: message", the format editors and CI logs understand.
  [[nodiscard]] std::string format() const;
};

class Diagnostics {
 public:
  void add(SourceLocation where, std::string field, std::string message);
  [[nodiscard]] bool empty() const { return items_.empty(); }
  [[nodiscard]] std::size_t size() const { return items_.size(); }
  [[nodiscard]] const std::vector<Diagnostic>& items() const { return items_; }
  /// All problems, one per line, sorted by position in the file.
  [[nodiscard]] std::string format() const;

 private:
  std::vector<Diagnostic> items_;
};

}  // namespace lode
