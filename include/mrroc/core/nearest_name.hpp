#pragma once
/// @file
/// "Did you mean ...?": the known name nearest to a mistyped one (task, plugin, solver names).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace mrroc {

/// The number of single-character edits that turn `a` into `b`: insertions, deletions,
/// substitutions and swaps of two neighbouring characters, each 1 (the optimal string alignment
/// distance). Case counts ('A' and 'a' differ).
[[nodiscard]] std::size_t edit_distance(const std::string& a, const std::string& b);

/// The name of `known` nearest to `name` by edit_distance, when it is close enough to be a typing
/// mistake: at most a third of `name`'s length (at least 1, at most 3 edits), and fewer edits than
/// `name` has characters. Of equally near names, the first in `known`'s order. Nothing for an
/// empty `name`, an empty `known` or a name far from all of them; `name` itself when it is known.
[[nodiscard]] std::optional<std::string> nearest_name(const std::string& name,
                                                      const std::vector<std::string>& known);

}  // namespace mrroc
