#include "core/closest_name.h"

#include <algorithm>

namespace driftlab {

std::string closest_name(std::string_view word, const std::vector<std::string>& names) {
  // A few edits (one in three characters, at least two) away, or a unique name it begins.
  std::string best;
  size_t best_distance = std::max<size_t>(2, word.size() / 3) + 1;
  std::vector<std::string> prefixed;
  for (const auto& n : names) {
    if (n.size() > word.size() && n.compare(0, word.size(), word) == 0 && word.size() >= 3) prefixed.push_back(n);
    const size_t d = edit_distance(word, n);
    if (d < best_distance) {
      best_distance = d;
      best = n;
    }
  }
  if (best.empty() && prefixed.size() == 1) return prefixed.front();
  return best;
}

size_t edit_distance(std::string_view a, std::string_view b) {
  // Damerau-Levenshtein (optimal string alignment): a swap of two neighbours ("daignose") is one edit.
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

}  // namespace driftlab
