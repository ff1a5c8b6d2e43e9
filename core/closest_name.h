// A guess at what a mistyped word meant ("did you mean 'diagnose'?"), for the command line's commands and options
// and a config file's keys.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace driftlab {

/// The number of single-character edits (insert, delete, replace, swap two neighbours) from a to b.
size_t edit_distance(std::string_view a, std::string_view b);
/// The name of names a mistyped word most likely meant (a few edits away, or the one name it begins), or "".
std::string closest_name(std::string_view word, const std::vector<std::string>& names);

}  // namespace driftlab
