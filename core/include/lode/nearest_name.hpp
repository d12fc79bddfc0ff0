// "Did you mean ...?" for a misspelt name: the known name nearest to it by edit distance
// (insertions, deletions, substitutions), if it is near enough to be a typo of it.
#pragma once

#include <string>
#include <vector>

namespace lode {

/// Levenshtein distance between `a` and `b`.
std::size_t edit_distance(const std::string& a, const std::string& b);

/// The name of `known` nearest to `unknown`, or "" when none is within max(2, length / 3)
/// edits (a name that far off is another name, not a typo).
std::string nearest_name(const std::vector<std::string>& known, const std::string& unknown);

}  // namespace lode
