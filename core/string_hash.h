// Transparent string hashing, so maps keyed by std::string can be searched with a string_view (no copy):
// std::unordered_map<std::string, T, StringHash, std::equal_to<>>.
#pragma once

#include <cstddef>
#include <functional>
#include <string_view>

namespace driftlab {

struct StringHash {
  using is_transparent = void;
  size_t operator()(std::string_view s) const { return std::hash<std::string_view>{}(s); }
};

}  // namespace driftlab
