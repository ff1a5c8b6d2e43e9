// Text files of numbers, one record a line (TUM, KITTI, EuRoC trajectories, relations): the lines that hold data
// and the numbers on them, correctly rounded and fast. Internal to analyzers/.
#pragma once

#include <cstddef>
#include <cstring>
#include <string_view>

namespace driftlab::analyzers::internal {

/// Parses the numbers of [p, end), separated by spaces, tabs or commas, into out (room for max): how many it
/// found, max + 1 when there are more, -1 when something is not a number. Numbers of up to 19 digits forming an
/// integer of at most 2^53 with at most 22 decimals (what trajectory files hold) take Clinger's fast path (an
/// integer and a power of ten, both exact in a double, so one division rounds correctly); others go to
/// std::from_chars. Both give the correctly rounded double, as numpy does.
int parse_numbers(const char* p, const char* end, double* out, int max);

/// Calls f(line_number, begin, end) (1-based; begin past leading blanks, end before the newline) for every line of
/// text that is not blank and does not start with '#'; stops early when f returns false.
template <typename F>
void for_each_data_line(std::string_view text, F&& f) {
  const char* p = text.data();
  const char* end = p + text.size();
  for (size_t line = 1; p < end; ++line) {
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
    if (eol == nullptr) eol = end;
    const char* q = p;
    while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) ++q;
    if (q < eol && *q != '#' && !f(line, q, eol)) return;
    p = eol + 1;
  }
}

}  // namespace driftlab::analyzers::internal
